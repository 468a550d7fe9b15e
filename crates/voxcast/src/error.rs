//! Typed errors of the library. Every error that comes from user input names
//! the file, the field and what was expected, so the CLI can print it as is.

use std::path::{Path, PathBuf};

/// The library's error type. Its text quotes what files say through
/// [`quote`]: control bytes are escaped and long values cut, so a hostile
/// header cannot drive the terminal or flood it.
#[derive(Debug)]
pub enum Error {
    /// An operating-system error while reading or writing `path` (its text
    /// carries the OS error, so it is not repeated as a `source`).
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    /// A file whose content does not match its format: `field` holds what was
    /// found, `expected` what the format (or the rest of the file) demands.
    Format {
        path: PathBuf,
        field: String,
        message: String,
    },
    /// A format or a variant of one that voxcast does not read (yet).
    Unsupported { path: PathBuf, message: String },
    /// Invalid parameters that did not come from a file (command line, scene).
    Invalid(String),
    /// A setting with a value out of its range, named by its scene field
    /// (`camera.fov`, `render.step`, …), from flags or a scene alike.
    Field(FieldError),
    /// A render stopped early because its cancel flag was raised
    /// ([`crate::render::Renderer::render_cancellable`]).
    Cancelled,
}

impl std::fmt::Display for Error {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Error::Io { path, source } => write!(f, "{}: {source}", quote_path(path)),
            Error::Format {
                path,
                field,
                message,
            } => write!(
                f,
                "{}: field `{}`: {}",
                quote_path(path),
                quote_cut(field, 120),
                quote(message)
            ),
            Error::Unsupported { path, message } => {
                write!(f, "{}: unsupported: {}", quote_path(path), quote(message))
            }
            Error::Invalid(m) => f.write_str(&quote(m)),
            Error::Field(e) => f.write_str(&quote(&e.to_string())),
            Error::Cancelled => f.write_str("the render was cancelled"),
        }
    }
}

impl std::error::Error for Error {}

/// Longest message shown whole; longer ones keep their head and tail.
const MAX_MESSAGE: usize = 600;

/// `s` made safe to print: control characters (but newlines) escaped as
/// `\x1b`, `\u{9b}`…, and cut in the middle when longer than 600
/// characters (the head names the field, the tail says what was expected).
pub fn quote(s: &str) -> String {
    quote_cut(s, MAX_MESSAGE)
}

/// [`quote`] with a chosen length.
pub fn quote_cut(s: &str, max: usize) -> String {
    let escaped = escape_controls(s);
    let n = escaped.chars().count();
    if n <= max {
        return escaped;
    }
    let tail = max / 4;
    let head = max - tail;
    let mut out: String = escaped.chars().take(head).collect();
    out.push_str(&format!(" …[{} characters cut]… ", n - head - tail));
    out.extend(escaped.chars().skip(n - tail));
    out
}

/// A path made safe to print (see [`quote`]).
pub fn quote_path(p: &Path) -> String {
    quote_cut(&p.display().to_string(), 300)
}

fn escape_controls(s: &str) -> String {
    if !s.chars().any(needs_escape) {
        return s.to_string();
    }
    let mut out = String::with_capacity(s.len() + 8);
    for c in s.chars() {
        match c {
            '\t' => out.push_str("\\t"),
            '\r' => out.push_str("\\r"),
            c if needs_escape(c) && (c as u32) < 0x100 => {
                out.push_str(&format!("\\x{:02x}", c as u32))
            }
            c if needs_escape(c) => out.push_str(&format!("\\u{{{:x}}}", c as u32)),
            c => out.push(c),
        }
    }
    out
}

/// Control characters (C0 but newline, DEL, C1), bidirectional overrides
/// and the replacement character from undecodable bytes.
fn needs_escape(c: char) -> bool {
    (c.is_control() && c != '\n') || matches!(c, '\u{202a}'..='\u{202e}' | '\u{2066}'..='\u{2069}')
}

/// Shorthand for results of this library.
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// An I/O error on `path`.
    pub fn io(path: impl AsRef<Path>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.as_ref().to_path_buf(),
            source,
        }
    }

    /// A format error: `field` of `path` is wrong; `message` says what was
    /// found and what was expected.
    pub fn format(
        path: impl AsRef<Path>,
        field: impl Into<String>,
        message: impl Into<String>,
    ) -> Self {
        Error::Format {
            path: path.as_ref().to_path_buf(),
            field: field.into(),
            message: message.into(),
        }
    }

    /// An unsupported variant of a format.
    pub fn unsupported(path: impl AsRef<Path>, message: impl Into<String>) -> Self {
        Error::Unsupported {
            path: path.as_ref().to_path_buf(),
            message: message.into(),
        }
    }

    /// Invalid parameters (not from a file).
    pub fn invalid(message: impl Into<String>) -> Self {
        Error::Invalid(message.into())
    }
}

/// A setting a user may get wrong, named by its field in a scene file
/// (`camera.fov`, `render.medium.albedo`, `transfer.window`, …) with what
/// is wrong, starting with the value: `0: must be between 1 and 170
/// degrees`. Every check of the scene's values returns one, so the command
/// line can name the flag that set the field, a scene file the file and the
/// field, and the library the field.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FieldError {
    pub field: String,
    pub message: String,
}

impl FieldError {
    pub fn new(field: impl Into<String>, message: impl Into<String>) -> Self {
        FieldError {
            field: field.into(),
            message: message.into(),
        }
    }

    /// The same error under an enclosing field: `medium.scale` in `render`
    /// is `render.medium.scale`.
    pub fn within(mut self, outer: &str) -> Self {
        self.field = format!("{outer}.{}", self.field);
        self
    }
}

impl std::fmt::Display for FieldError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.field, self.message)
    }
}

impl std::error::Error for FieldError {}

impl From<FieldError> for Error {
    fn from(e: FieldError) -> Self {
        Error::Field(e)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn file_text_in_messages_is_escaped_and_cut() {
        let e = Error::format(
            "a\x1b[2Jb.nrrd",
            "type",
            format!("`\x1b]0;pwned\x07{}` is not a type", "v".repeat(3000)),
        );
        let s = e.to_string();
        assert!(!s.chars().any(|c| c.is_control()), "{s:?}");
        assert!(s.contains("\\x1b[2J") && s.contains("\\x07"), "{s}");
        assert!(s.len() < 900 && s.ends_with("is not a type"), "{s}");
        assert!(s.contains("characters cut"), "{s}");
    }

    #[test]
    fn os_errors_are_said_once() {
        let io = std::fs::read("/no/such/file").unwrap_err();
        let e = Error::io("/no/such/file", io);
        let chain = format!("{:#}", anyhow_like(&e));
        assert_eq!(chain.matches("os error").count(), 1, "{chain}");
    }

    /// The message and its sources, as `anyhow`'s `{:#}` prints them.
    fn anyhow_like(e: &dyn std::error::Error) -> String {
        let mut s = e.to_string();
        let mut src = e.source();
        while let Some(x) = src {
            s += &format!(": {x}");
            src = x.source();
        }
        s
    }
}
