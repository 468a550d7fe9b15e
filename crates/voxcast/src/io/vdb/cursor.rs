//! The bounds-checked little-endian cursor every read of the file goes
//! through: a size the file claims past its end is an error, not a panic.

use crate::error::{Error, Result};
use std::path::Path;

/// Bounds-checked little-endian cursor over the file's bytes.
pub(super) struct Cursor<'a> {
    pub(super) buf: &'a [u8],
    pub(super) pos: usize,
    pub(super) path: &'a Path,
}

impl<'a> Cursor<'a> {
    pub(super) fn err(&self, field: &str, msg: impl Into<String>) -> Error {
        Error::format(self.path, field, msg)
    }
    pub(super) fn remaining(&self) -> usize {
        self.buf.len().saturating_sub(self.pos)
    }
    pub(super) fn bytes(&mut self, n: usize, field: &str) -> Result<&'a [u8]> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.buf.len());
        match end {
            Some(end) => {
                let s = &self.buf[self.pos..end];
                self.pos = end;
                Ok(s)
            }
            None => Err(self.err(
                field,
                format!(
                    "needs {n} bytes at offset {}, the file ends at {} (truncated?)",
                    self.pos,
                    self.buf.len()
                ),
            )),
        }
    }
    pub(super) fn arr<const N: usize>(&mut self, field: &str) -> Result<[u8; N]> {
        let s = self.bytes(N, field)?;
        let mut a = [0u8; N];
        a.copy_from_slice(s);
        Ok(a)
    }
    pub(super) fn u8(&mut self, field: &str) -> Result<u8> {
        Ok(self.arr::<1>(field)?[0])
    }
    pub(super) fn u32(&mut self, field: &str) -> Result<u32> {
        Ok(u32::from_le_bytes(self.arr(field)?))
    }
    pub(super) fn i32(&mut self, field: &str) -> Result<i32> {
        Ok(i32::from_le_bytes(self.arr(field)?))
    }
    pub(super) fn i64(&mut self, field: &str) -> Result<i64> {
        Ok(i64::from_le_bytes(self.arr(field)?))
    }
    pub(super) fn f64(&mut self, field: &str) -> Result<f64> {
        Ok(f64::from_le_bytes(self.arr(field)?))
    }
    pub(super) fn string(&mut self, field: &str) -> Result<String> {
        let n = self.u32(field)? as usize;
        if n > self.remaining() {
            return Err(self.err(
                field,
                format!(
                    "string of {n} bytes claimed, only {} bytes left in the file",
                    self.remaining()
                ),
            ));
        }
        let s = self.bytes(n, field)?;
        Ok(String::from_utf8_lossy(s).into_owned())
    }
    pub(super) fn seek(&mut self, pos: i64, field: &str) -> Result<()> {
        match usize::try_from(pos) {
            Ok(p) if p <= self.buf.len() => {
                self.pos = p;
                Ok(())
            }
            _ => Err(self.err(
                field,
                format!(
                    "offset {pos} is outside the file ({} bytes)",
                    self.buf.len()
                ),
            )),
        }
    }
    /// Skips a metadata block (count, then name, type, sized value each).
    pub(super) fn skip_metadata(&mut self, field: &str) -> Result<()> {
        let count = self.u32(field)? as usize;
        if count.saturating_mul(12) > self.remaining() {
            return Err(self.err(
                field,
                format!(
                    "{count} metadata entries claimed, only {} bytes left",
                    self.remaining()
                ),
            ));
        }
        for _ in 0..count {
            self.string(field)?;
            self.string(field)?;
            let n = self.u32(field)? as usize;
            self.bytes(n, field)?;
        }
        Ok(())
    }
}
