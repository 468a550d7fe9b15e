//! Typed errors of the library. Every error that comes from user input names
//! the file, the field and what was expected, so the CLI can print it as is.

use std::path::{Path, PathBuf};

/// The library's error type.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// An operating-system error while reading or writing `path`.
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A file whose content does not match its format: `field` holds what was
    /// found, `expected` what the format (or the rest of the file) demands.
    #[error("{path}: field `{field}`: {message}")]
    Format {
        path: PathBuf,
        field: String,
        message: String,
    },
    /// A format or a variant of one that voxcast does not read (yet).
    #[error("{path}: unsupported: {message}")]
    Unsupported { path: PathBuf, message: String },
    /// Invalid parameters that did not come from a file (command line, scene).
    #[error("{0}")]
    Invalid(String),
    /// A render stopped early because its cancel flag was raised
    /// ([`crate::render::Renderer::render_cancellable`]).
    #[error("the render was cancelled")]
    Cancelled,
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
