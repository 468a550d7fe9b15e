//! `.sf` slice files: the header, the frame times and one frame's values.

use super::data::{le_f32, le_i32, open_data, pick_time, read_at};
use crate::error::{Error, Result};
use std::path::Path;

/// One frame of a `.sf` slice file.
#[derive(Clone, Debug)]
pub struct SfFrame {
    pub time: f32,
    /// The times of all complete frames.
    pub times: Vec<f32>,
    /// Node bounds i1 i2 j1 j2 k1 k2.
    pub bounds: [usize; 6],
    /// Values, i fastest.
    pub values: Vec<f32>,
}

/// Reads the frame nearest `time` (the last when `None`) of a `.sf` file;
/// only that frame's values are read.
pub fn read_sf_frame(path: &Path, time: Option<f64>) -> Result<SfFrame> {
    let (mut r, len) = open_data(path, "SLCF", path)?;
    let h = read_at(&mut r, path, len, 0, 146, "header")?;
    for k in 0..3 {
        if le_i32(&h, 38 * k) != 30 || le_i32(&h, 38 * k + 34) != 30 {
            return Err(Error::format(path, "header", "bad label record markers"));
        }
    }
    if le_i32(&h, 114) != 24 || le_i32(&h, 142) != 24 {
        return Err(Error::format(path, "header", "bad bounds record markers"));
    }
    let b: Vec<i32> = (0..6).map(|a| le_i32(&h, 118 + 4 * a)).collect();
    if (0..3).any(|a| b[2 * a] < 0 || b[2 * a + 1] < b[2 * a]) {
        return Err(Error::format(path, "bounds", format!("{b:?}")));
    }
    let bounds = [0, 1, 2, 3, 4, 5].map(|a| b[a] as usize);
    let dims = [0, 1, 2].map(|a| bounds[2 * a + 1] - bounds[2 * a] + 1);
    let np = crate::volume::checked_voxel_count(dims.map(|d| d as u64))
        .map_err(|m| Error::format(path, "bounds", m))?;
    // frame = [4|t|4] (12 bytes) + [4N|data|4N] (4N+8 bytes)
    let fsize = 12 + 4 * np as u64 + 8;
    let nframes = (len - 146) / fsize;
    if nframes == 0 {
        return Err(Error::format(
            path,
            "frames",
            "the file holds no complete frame",
        ));
    }
    let mut times = Vec::with_capacity(nframes as usize);
    for k in 0..nframes {
        let off = 146 + k * fsize;
        let t = read_at(&mut r, path, len, off, 20, &format!("frame {k}"))?;
        if le_i32(&t, 0) != 4 || le_i32(&t, 8) != 4 || le_i32(&t, 12) as i64 != 4 * np as i64 {
            return Err(Error::format(
                path,
                format!("frame {k}"),
                "bad record markers",
            ));
        }
        times.push(le_f32(&t, 4));
    }
    let idx = pick_time(
        path,
        &times.iter().map(|&t| t as f64).collect::<Vec<_>>(),
        time,
    )?;
    let d = read_at(
        &mut r,
        path,
        len,
        146 + idx as u64 * fsize + 16,
        4 * np,
        "data",
    )?;
    let v = d
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    Ok(SfFrame {
        time: times[idx],
        times,
        bounds,
        values: v,
    })
}
