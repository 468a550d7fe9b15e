//! Writing a volume as an attached NRRD file (`.nrrd`): the simulators
//! (smoke, clouds) store their frames this way, so every tool that reads
//! NRRD — voxcast, ParaView, 3D Slicer, teem — opens them.
//!
//! The header carries `sizes`, `spacings`, `space origin` (as a 3-D
//! `space dimension`) and, when known, `sample units` and the variable name
//! as a `content:` line; the data follow raw little-endian or gzip-compressed.

use crate::error::Result;
use crate::files::write_file;
use crate::volume::{Volume, VoxelData};
use std::io::Write;
use std::path::Path;

/// Data encoding of a written NRRD file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Encoding {
    /// Raw little-endian bytes: fastest to write and read.
    Raw,
    /// gzip (deflate, fast level): smaller for smoke and clouds, which are
    /// mostly empty.
    Gzip,
}

/// Writes `volume` to `path` (atomically: a temporary file renamed into
/// place, so an interrupted write never leaves a partial frame).
pub fn write(path: &Path, volume: &Volume, encoding: Encoding) -> Result<()> {
    let [nx, ny, nz] = volume.dims();
    let s = volume.spacing();
    let o = volume.origin();
    let ty = match volume.data() {
        VoxelData::U8(_) => "uint8",
        VoxelData::U16(_) => "uint16",
        VoxelData::I16(_) => "int16",
        VoxelData::F32(_) => "float",
    };
    let mut header = String::from("NRRD0004\n# written by voxcast\n");
    if let Some(name) = &volume.name {
        // `content:` is a single line; keep it printable.
        let clean: String = name.chars().filter(|c| !c.is_control()).collect();
        header += &format!("content: {clean}\n");
    }
    header += &format!(
        "type: {ty}\ndimension: 3\nspace dimension: 3\nsizes: {nx} {ny} {nz}\n\
         space directions: ({},0,0) (0,{},0) (0,0,{})\nspace origin: ({},{},{})\n",
        s.x, s.y, s.z, o.x, o.y, o.z
    );
    if let Some(u) = &volume.units {
        let clean: String = u.chars().filter(|c| !c.is_control()).collect();
        header += &format!("sample units: {clean}\n");
    }
    header += match encoding {
        Encoding::Raw => "encoding: raw\n",
        Encoding::Gzip => "encoding: gzip\n",
    };
    header += "endian: little\n\n";
    write_file(path, |w| {
        w.write_all(header.as_bytes())?;
        match encoding {
            Encoding::Raw => write_le(volume.data(), w),
            Encoding::Gzip => {
                let mut gz = flate2::write::GzEncoder::new(w, flate2::Compression::fast());
                write_le(volume.data(), &mut gz)?;
                gz.finish()?;
                Ok(())
            }
        }
    })
}

/// The voxels as little-endian bytes, in chunks (no copy of the whole volume).
fn write_le(data: &VoxelData, w: &mut impl Write) -> std::io::Result<()> {
    const CHUNK: usize = 1 << 16;
    let mut buf = Vec::with_capacity(CHUNK * 4);
    macro_rules! chunks {
        ($v:expr) => {
            for c in $v.chunks(CHUNK) {
                buf.clear();
                for x in c {
                    buf.extend_from_slice(&x.to_le_bytes());
                }
                w.write_all(&buf)?;
            }
        };
    }
    match data {
        VoxelData::U8(v) => w.write_all(v)?,
        VoxelData::U16(v) => chunks!(v),
        VoxelData::I16(v) => chunks!(v),
        VoxelData::F32(v) => chunks!(v),
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn round_trips_every_type_and_encoding() {
        let dir = tempfile::tempdir().unwrap();
        let dims = [5, 4, 3];
        let n = 60;
        let datas = [
            VoxelData::U8((0..n).map(|i| i as u8 * 3).collect()),
            VoxelData::U16((0..n).map(|i| i as u16 * 1000).collect()),
            VoxelData::I16((0..n).map(|i| i as i16 * 500 - 9000).collect()),
            VoxelData::F32((0..n).map(|i| i as f32 * 0.37 - 4.0).collect()),
        ];
        for data in datas {
            for enc in [Encoding::Raw, Encoding::Gzip] {
                let mut v = Volume::new(
                    dims,
                    Vec3::new(0.5, 1.0, 2.5),
                    Vec3::new(-1.0, 2.0, 3.5),
                    data.clone(),
                )
                .unwrap();
                v.units = Some("kg/m^3".into());
                let p = dir
                    .path()
                    .join(format!("v_{:?}_{enc:?}.nrrd", data.scalar_type()));
                write(&p, &v, enc).unwrap();
                let back = crate::io::nrrd::read(&p).unwrap();
                assert_eq!(back.dims(), dims);
                assert_eq!(back.spacing(), v.spacing());
                assert_eq!(back.origin(), v.origin());
                assert_eq!(back.scalar_type(), v.scalar_type());
                assert_eq!(back.units.as_deref(), Some("kg/m^3"));
                for i in 0..n {
                    assert_eq!(back.data().get(i), v.data().get(i));
                }
            }
        }
    }
}
