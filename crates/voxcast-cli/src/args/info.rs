//! `voxcast info`.

use super::scene::OpenArgs;
use clap::Args;

#[derive(Args)]
pub struct InfoArgs {
    /// Volume: a file, folder, glob, or builtin:NAME.
    pub input: String,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub open: OpenArgs,
}
