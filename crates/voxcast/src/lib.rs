//! voxcast — volume rendering by ray casting.
//!
//! The data flows one way: a file or generator gives a [`Volume`]
//! ([`io`], [`builtin`]); a [`Scene`](scene::Scene) adds the transfer
//! function, camera and method; a renderer ([`render`]) turns it into an
//! [`Image`](image::Image) and [`RenderStats`](render::RenderStats); images are
//! written as PNG/EXR and compared with [`metrics`].

pub mod error;
pub mod io;
pub mod volume;

pub use error::{Error, Result};
pub use volume::{ScalarType, Volume, VoxelData};
#[doc(hidden)]
pub mod testdata;
