//! `voxcast compare`.

use clap::Args;
use std::path::PathBuf;

#[derive(Args)]
pub struct CompareArgs {
    /// First image (PNG or EXR).
    pub a: PathBuf,
    /// Second image (PNG or EXR).
    pub b: PathBuf,
    /// Print JSON (`psnr_db`, `ssim`).
    #[arg(long)]
    pub json: bool,
}
