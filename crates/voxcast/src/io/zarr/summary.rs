//! What `voxcast info` says of a store.

use super::ZarrStore;
use crate::volume::ChunkedSource;

impl ZarrStore {
    /// Lines for `voxcast info`: the format, axes, type, and each level's
    /// path, dims, voxel size, chunks, codecs and decoded size.
    pub fn summary(&self) -> Vec<String> {
        let i = &self.info;
        let mut out = vec![format!(
            "Zarr v{}{}, {} levels, {} (fill {})",
            i.zarr_format,
            i.ome_version
                .as_ref()
                .map(|v| format!(", OME-Zarr {v}"))
                .unwrap_or_else(|| ", no OME-Zarr metadata".into()),
            self.levels.len(),
            i.stored.name(),
            i.fill
        )];
        let axes: Vec<String> = i
            .axes
            .iter()
            .map(|(n, k, u)| {
                let mut s = format!("{n} ({k}");
                if let Some(u) = u {
                    s += &format!(", {u}");
                }
                s + ")"
            })
            .collect();
        out.push(format!("axes {}", axes.join(", ")));
        if !i.lead_index.is_empty() {
            let lead: Vec<String> = i
                .axes
                .iter()
                .zip(&i.lead_index)
                .map(|((n, _, _), k)| format!("{n} = {k}"))
                .collect();
            out.push(format!(
                "reading {} (--time picks t, --var the channel{})",
                lead.join(", "),
                if i.channels.is_empty() {
                    String::new()
                } else {
                    format!(": {}", i.channels.join(", "))
                }
            ));
        }
        let ty = self.scalar_type();
        for (l, (lv, li)) in self.levels.iter().zip(&i.levels).enumerate() {
            // Sharded: the chunks above are the shards' inner chunks.
            let shard = match li.subchunk_shape {
                Some(_) => format!(
                    " in shard files of {} (array order)",
                    li.chunk_shape
                        .iter()
                        .map(|c| c.to_string())
                        .collect::<Vec<_>>()
                        .join("×")
                ),
                None => String::new(),
            };
            out.push(format!(
                "level {l} [{}]: {}×{}×{}, voxel {} × {} × {}, chunks {}×{}×{}{shard}, {}, {} decoded{}",
                if li.path.is_empty() { "/" } else { &li.path },
                lv.dims[0],
                lv.dims[1],
                lv.dims[2],
                lv.spacing.x,
                lv.spacing.y,
                lv.spacing.z,
                lv.chunk[0],
                lv.chunk[1],
                lv.chunk[2],
                if li.codecs.is_empty() {
                    "uncompressed".to_string()
                } else {
                    li.codecs.join(" + ")
                },
                crate::render::outofcore::human_bytes(lv.bytes(ty)),
                if li.has_ranges { ", chunk ranges" } else { "" }
            ));
        }
        out
    }
}
