//! voxcast — volume rendering by ray casting.
//!
//! The data flows one way: a file or generator gives a [`Volume`]
//! ([`io`], [`builtin`]); a [`Scene`] adds the transfer function
//! ([`transfer`]), the camera ([`camera`]) and the method; the renderer
//! ([`render`]) turns it into an [`Image`] and [`RenderStats`]; images are
//! written as PNG/EXR and compared with [`metrics`].
//!
//! The simulators that make volumes (smoke, clouds) are the `voxcast-sim`
//! crate; the benchmarks of the methods and their charts are `voxcast-bench`.

pub mod builtin;
pub mod camera;
pub mod error;
pub mod files;
#[doc(hidden)]
pub mod fuzz_support;
pub mod geometry;
pub mod image;
pub mod io;
pub mod metrics;
pub mod render;
pub mod scene;
pub mod transfer;
pub mod volume;

#[doc(hidden)]
pub mod testdata;

pub use error::{Error, FieldError, Result};
pub use image::Image;
pub use render::RenderStats;
pub use scene::Scene;
pub use volume::{ScalarType, Volume, VoxelData};
