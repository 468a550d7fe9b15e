//! voxcast's readers over C and C++ libraries, each behind a feature:
//!
//! * `wrf`: WRF output (NetCDF-4) through the system's libnetcdf;
//! * `minc`: MINC-2 (`.mnc`, HDF5) through the same libnetcdf;
//! * `jpeg-ls`: JPEG-LS DICOM through CharLS (built from source).
//!
//! They live above the core crate and give it their entry points at run
//! time: call [`install`] once, before opening files, and `voxcast::io::open`
//! (and `voxcast info`, series, DICOM folders) read these formats too. The
//! CLI does so at start. See `voxcast::io::external` for why they are not
//! features of the core crate.

#[cfg(feature = "minc")]
pub mod minc;
#[cfg(feature = "wrf")]
pub mod wrf;

/// The readers this build has, for `voxcast::io::external::install`.
pub fn readers() -> voxcast::io::external::Readers {
    #[allow(unused_mut)]
    let mut r = voxcast::io::external::Readers::default();
    #[cfg(feature = "wrf")]
    {
        r.wrf = Some(voxcast::io::external::WrfReader {
            read: wrf::read,
            summary: wrf::summary,
            times: wrf::times,
        });
    }
    #[cfg(feature = "minc")]
    {
        r.minc = Some(voxcast::io::external::MincReader {
            read: minc::read,
            summary: minc::summary,
        });
    }
    #[cfg(feature = "jpeg-ls")]
    {
        r.jpeg_ls = Some(decode_jpeg_ls);
    }
    r
}

/// Gives the core crate the readers this build has. Call it once at start;
/// later calls change nothing.
pub fn install() {
    voxcast::io::external::install(readers());
}

/// Decodes one JPEG-LS frame with CharLS: one component of 8 or 16 bits,
/// as large as the DICOM header says (checked before CharLS allocates).
/// Samples come little endian (CharLS writes native order, and this crate
/// builds only for little-endian targets with this feature).
#[cfg(feature = "jpeg-ls")]
pub fn decode_jpeg_ls(
    frame: &[u8],
    shape: voxcast::io::external::FrameShape,
) -> Result<Vec<u8>, String> {
    const _: () = assert!(
        cfg!(target_endian = "little"),
        "JPEG-LS samples are taken as little endian"
    );
    let bits = shape.bits_allocated;
    if bits != 8 && bits != 16 {
        return Err(format!(
            "BitsAllocated {bits}: JPEG-LS is decoded for 8 and 16 bits"
        ));
    }
    let info = charls::CharLS::default()
        .get_frame_info(frame)
        .map_err(|e| format!("CharLS: {e}"))?;
    let (w, h, b, c) = (
        info.width,
        info.height,
        info.bits_per_sample,
        info.component_count,
    );
    if w != shape.columns || h != shape.rows || c != 1 || b < 2 || b > bits as i32 {
        return Err(format!(
            "the JPEG-LS frame is {w} × {h}, {c} component(s) of {b} bits, but the header says Columns {} × Rows {}, one sample of at most BitsAllocated {bits}",
            shape.columns, shape.rows
        ));
    }
    charls::CharLS::default()
        .decode(frame)
        .map_err(|e| format!("CharLS: {e}"))
}
