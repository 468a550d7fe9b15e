//! A Blosc1 decoder for the chunks OpenVDB writes: the 16-byte header, the
//! block offsets, per-block split streams, LZ4 raw blocks and the byte
//! unshuffle. Other codecs and bit shuffle are reported as unsupported.

pub(super) enum BloscError {
    Bad(String),
    Unsupported(String),
}

/// Decodes one Blosc1 frame to exactly `expected` bytes (OpenVDB pads tiny
/// buffers before compressing, so the frame may hold more).
pub(super) fn blosc_decode(
    src: &[u8],
    expected: usize,
) -> std::result::Result<Vec<u8>, BloscError> {
    let bad = |m: String| BloscError::Bad(m);
    if src.len() < 16 {
        return Err(bad(format!(
            "{} bytes, shorter than the 16-byte header",
            src.len()
        )));
    }
    let flags = src[2];
    let typesize = src[3] as usize;
    let rd = |o: usize| u32::from_le_bytes([src[o], src[o + 1], src[o + 2], src[o + 3]]) as usize;
    let nbytes = rd(4);
    let blocksize = rd(8);
    let cbytes = rd(12);
    if cbytes > src.len() {
        return Err(bad(format!(
            "claims {cbytes} bytes, the chunk holds {}",
            src.len()
        )));
    }
    if nbytes < expected || nbytes > expected.max(1024) {
        return Err(bad(format!("holds {nbytes} bytes, expected {expected}")));
    }
    let src = &src[..cbytes];
    let mut out = vec![0u8; nbytes];
    if flags & 0x2 != 0 {
        // Stored (memcpyed).
        let end = 16usize
            .checked_add(nbytes)
            .filter(|&e| e <= src.len())
            .ok_or_else(|| bad("stored chunk is truncated".into()))?;
        out.copy_from_slice(&src[16..end]);
        out.truncate(expected);
        return Ok(out);
    }
    if flags & 0x4 != 0 {
        return Err(BloscError::Unsupported("Blosc bit shuffle".into()));
    }
    let codec = flags >> 5;
    if codec != 1 {
        let name = match codec {
            0 => "BloscLZ",
            2 => "Snappy",
            3 => "zlib",
            4 => "Zstd",
            _ => "unknown",
        };
        return Err(BloscError::Unsupported(format!(
            "Blosc codec {name} (only LZ4 is read)"
        )));
    }
    if nbytes == 0 {
        return Ok(out);
    }
    if blocksize == 0 || typesize == 0 {
        return Err(bad("block size or type size 0".into()));
    }
    let nblocks = nbytes.div_ceil(blocksize);
    let starts_end = nblocks
        .checked_mul(4)
        .and_then(|b| b.checked_add(16))
        .filter(|&e| e <= src.len())
        .ok_or_else(|| bad(format!("{nblocks} blocks do not fit the chunk")))?;
    let shuffle = flags & 0x1 != 0 && typesize > 1;
    let dont_split = flags & 0x10 != 0;
    let mut tmp = vec![0u8; blocksize.min(nbytes)];
    for j in 0..nblocks {
        let start = rd(16 + 4 * j);
        if start < starts_end || start >= src.len() {
            return Err(bad(format!(
                "block {j} starts at {start}, outside the chunk"
            )));
        }
        let bstart = j * blocksize;
        let bsize = blocksize.min(nbytes - bstart);
        let leftover = bsize < blocksize;
        let rule = if !dont_split && typesize <= 16 && bsize / typesize >= 128 && !leftover {
            typesize
        } else {
            1
        };
        let dst = if shuffle {
            &mut tmp[..bsize]
        } else {
            &mut out[bstart..bstart + bsize]
        };
        let mut ok = false;
        for ns in [rule, if rule == 1 { typesize } else { 1 }] {
            if ns > 0 && bsize % ns == 0 && decode_block(&src[start..], dst, ns) {
                ok = true;
                break;
            }
        }
        if !ok {
            return Err(bad(format!("block {j} does not decode")));
        }
        if shuffle {
            let ne = bsize / typesize;
            let o = &mut out[bstart..bstart + bsize];
            for t in 0..typesize {
                for i in 0..ne {
                    o[i * typesize + t] = tmp[t * ne + i];
                }
            }
            let tail = ne * typesize;
            o[tail..].copy_from_slice(&tmp[tail..bsize]);
        }
    }
    out.truncate(expected);
    Ok(out)
}

/// One Blosc block of `nsplits` streams, each an i32 size then LZ4 data
/// (or the raw bytes when the size equals the stream's length).
fn decode_block(src: &[u8], dst: &mut [u8], nsplits: usize) -> bool {
    let ne = dst.len() / nsplits;
    let mut pos = 0usize;
    for s in 0..nsplits {
        let Some(h) = src.get(pos..pos + 4) else {
            return false;
        };
        let cb = i32::from_le_bytes([h[0], h[1], h[2], h[3]]);
        pos += 4;
        let Ok(cb) = usize::try_from(cb) else {
            return false;
        };
        let Some(data) = pos.checked_add(cb).and_then(|e| src.get(pos..e)) else {
            return false;
        };
        pos += cb;
        let d = &mut dst[s * ne..(s + 1) * ne];
        if cb == ne {
            d.copy_from_slice(data);
        } else if lz4_block(data, d) != Some(ne) {
            return false;
        }
    }
    true
}

/// Decodes an LZ4 raw block into `dst`; returns the bytes written.
pub(super) fn lz4_block(src: &[u8], dst: &mut [u8]) -> Option<usize> {
    let mut i = 0usize;
    let mut o = 0usize;
    loop {
        let token = *src.get(i)?;
        i += 1;
        let mut lit = (token >> 4) as usize;
        if lit == 15 {
            loop {
                let b = *src.get(i)?;
                i += 1;
                lit = lit.checked_add(b as usize)?;
                if b != 255 {
                    break;
                }
            }
        }
        let s = src.get(i..i.checked_add(lit)?)?;
        dst.get_mut(o..o.checked_add(lit)?)?.copy_from_slice(s);
        i += lit;
        o += lit;
        if i == src.len() {
            return Some(o);
        }
        let off = u16::from_le_bytes([*src.get(i)?, *src.get(i + 1)?]) as usize;
        i += 2;
        if off == 0 || off > o {
            return None;
        }
        let mut ml = (token & 15) as usize;
        if ml == 15 {
            loop {
                let b = *src.get(i)?;
                i += 1;
                ml = ml.checked_add(b as usize)?;
                if b != 255 {
                    break;
                }
            }
        }
        ml += 4;
        if o.checked_add(ml)? > dst.len() {
            return None;
        }
        for k in 0..ml {
            dst[o + k] = dst[o + k - off];
        }
        o += ml;
    }
}
