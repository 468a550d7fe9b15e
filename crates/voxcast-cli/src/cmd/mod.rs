//! The commands: one file per subcommand, each a `run` that takes its
//! arguments (`args/`), and the helpers two commands share: `device.rs`
//! (`--device` → the CPU or a GPU renderer) and `series.rs` (a series and
//! its frames for animate and bench-frames).

pub mod animate;
pub mod bench;
pub mod bench_frames;
pub mod cloud;
pub mod compare;
pub mod convert;
mod device;
pub mod info;
#[cfg(feature = "mpi")]
pub mod mpi;
pub mod presets;
pub mod render;
mod render_chunked;
mod series;
pub mod simulate;
pub mod view;
