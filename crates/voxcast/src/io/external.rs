//! Readers over C and C++ libraries, handed to this crate from one above it.
//!
//! NetCDF (WRF output, MINC-2) and JPEG-LS DICOM (CharLS) link C and C++
//! libraries, so they are optional. They live in the crate
//! `voxcast-native-io`, behind its features `wrf`, `minc` and `jpeg-ls`,
//! and give this crate their entry points once per process
//! (`voxcast_native_io::install()`; the CLI does so at start). `io::open`,
//! `io::header_summary`, `Series::open` and the DICOM reader then use them;
//! without them those inputs are refused, naming the feature.
//!
//! Why a hook and not features of this crate: a feature, or a feature it
//! turns on in a dependency (CharLS is a dicom-pixeldata feature), changes
//! this crate's build, and a build with the optional readers would compile
//! the library — all its ray loops — once more. Through the hook it reuses
//! the library of the default build.

use crate::error::Result;
use crate::io::OpenOptions;
use crate::volume::Volume;
use std::path::Path;
use std::sync::OnceLock;

/// WRF output (NetCDF-4): see `voxcast::io::wrf`.
#[derive(Clone, Copy)]
pub struct WrfReader {
    /// Reads the variable `opts.variable` at time index `opts.time`.
    pub read: fn(&Path, &OpenOptions) -> Result<Volume>,
    /// Lines describing the file for `voxcast info`.
    pub summary: fn(&Path) -> Result<Vec<String>>,
    /// The file's `Times` strings, one per time index.
    pub times: fn(&Path) -> Result<Vec<String>>,
}

/// MINC-2 (`.mnc`, HDF5): see `voxcast::io::minc`.
#[derive(Clone, Copy)]
pub struct MincReader {
    /// Reads the volume.
    pub read: fn(&Path) -> Result<Volume>,
    /// Lines describing the header for `voxcast info`.
    pub summary: fn(&Path) -> Result<Vec<String>>,
}

/// What the DICOM header says a frame holds: one sample per pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameShape {
    pub rows: u32,
    pub columns: u32,
    pub bits_allocated: u16,
}

/// Decodes one encapsulated DICOM frame (all its fragments, joined) to its
/// samples: right aligned, little endian, `bits_allocated / 8` bytes each.
/// A frame whose own header disagrees with `shape` is refused before
/// anything is allocated. The error is the codec's message.
pub type FrameDecoder = fn(frame: &[u8], shape: FrameShape) -> std::result::Result<Vec<u8>, String>;

/// The optional readers a process has.
#[derive(Clone, Copy, Default)]
pub struct Readers {
    pub wrf: Option<WrfReader>,
    pub minc: Option<MincReader>,
    /// JPEG-LS (transfer syntaxes 1.2.840.10008.1.2.4.80 and .81).
    pub jpeg_ls: Option<FrameDecoder>,
}

static READERS: OnceLock<Readers> = OnceLock::new();

/// Gives this process the optional readers. The first call wins; it returns
/// false (and changes nothing) when readers were installed before.
pub fn install(readers: Readers) -> bool {
    READERS.set(readers).is_ok()
}

/// The readers installed, or none.
pub fn installed() -> Readers {
    READERS.get().copied().unwrap_or_default()
}
