//! `voxcast convert`.

use super::scene::OpenArgs;
use clap::Args;
use std::path::PathBuf;

pub const CONVERT_HELP: &str = "\
Writes an OME-Zarr multiscale pyramid: level 0 is the input, each next level
the 2×2×2 mean of the one before, until a level fits in one chunk (or
--levels). Zarr v3 with OME-Zarr 0.5 metadata by default, v2 with OME-Zarr
0.4 with --zarr-version 2; napari, Neuroglancer, BigDataViewer and the zarr
and ome-zarr Python packages open either. Chunks that hold only zeros are not
written, and every chunk's value range is kept beside each level
(voxcast-chunk-ranges.bin), so voxcast skips transparent chunks without
reading them.

The store is written slab by slab. A built-in volume generated at any size
(--dims, --type), a raw file (--raw-dims, --raw-type) and a Zarr store
(level 0, or --level N: rechunk or recompress it) are read slab by slab too
and never exist whole in memory; other formats are read whole first. It is written under a temporary
name beside OUTPUT and renamed when complete; an existing OUTPUT is replaced
only with --overwrite, and only if it is a Zarr store.

Examples:
  voxcast convert ../shared/data/mr_head/HeadMRVolume.mhd -o head.zarr
  voxcast convert scan.nrrd -o scan.zarr --chunk 128 --compression blosc
  voxcast convert ct.raw --raw-dims 2048,2048,1500 --raw-type u16 -o ct.zarr
  voxcast convert old.zarr -o new.zarr --zarr-version 2 --chunk 32
  voxcast convert builtin:fractal --dims 2048,2048,2048 --type u16 -o big.zarr  # 16 GiB
  voxcast render big.zarr --memory-budget 2GiB -o big.png   # out of core";

#[derive(Args)]
pub struct ConvertArgs {
    /// Volume: a file, folder, glob, or builtin:NAME.
    pub input: String,
    /// The store to write: a folder that does not exist yet (e.g. scan.zarr).
    #[arg(short, long, value_name = "DIR")]
    pub output: PathBuf,
    /// Chunk edge in voxels (N, or X,Y,Z).
    #[arg(long, value_name = "N|X,Y,Z", default_value = "64")]
    pub chunk: String,
    /// Levels in all, level 0 included (default: halve until a level fits
    /// in one chunk).
    #[arg(long, value_name = "N")]
    pub levels: Option<usize>,
    /// Zarr version: 3 (OME-Zarr 0.5) or 2 (OME-Zarr 0.4).
    #[arg(long, value_name = "2|3", default_value_t = 3)]
    pub zarr_version: u8,
    /// Chunk compression: zstd, blosc (zstd inside, byte shuffle), gzip or
    /// none, with an optional level (zstd:9).
    #[arg(long, value_name = "CODEC[:LEVEL]", default_value = "zstd")]
    pub compression: String,
    /// For builtin:NAME: generate at this size (X,Y,Z), slab by slab.
    #[arg(long, value_name = "X,Y,Z")]
    pub dims: Option<String>,
    /// For builtin:NAME with --dims: the voxel type (u8, u16, i16, f32).
    #[arg(long = "type", value_name = "TYPE", default_value = "u8")]
    pub scalar_type: String,
    /// Replace OUTPUT if it is a Zarr store already.
    #[arg(long)]
    pub overwrite: bool,
    /// No messages on stderr.
    #[arg(short, long)]
    pub quiet: bool,
    #[command(flatten)]
    pub open: OpenArgs,
}
