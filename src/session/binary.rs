//! Little-endian values in a session's binary entries, read with bounds:
//! running out of bytes, or bytes left over, makes the entry corrupt (the
//! archive around it is whole, so it was written wrong or damaged).

use super::SessionError;
use std::io::{Read, Write};

/// Reads little-endian values from entry `name`.
pub(super) struct LeReader<R> {
    input: R,
    name: &'static str,
}

impl<R: Read> LeReader<R> {
    pub(super) fn new(input: R, name: &'static str) -> Self {
        Self { input, name }
    }

    /// Fills `out` from the entry.
    pub(super) fn fill(&mut self, out: &mut [u8]) -> Result<(), SessionError> {
        self.input
            .read_exact(out)
            .map_err(|e| read_error(self.name, &e))
    }

    pub(super) fn u8s(&mut self, n: usize) -> Result<Vec<u8>, SessionError> {
        let mut v = alloc(n, self.name)?;
        v.resize(n, 0);
        self.fill(&mut v)?;
        Ok(v)
    }

    pub(super) fn u32(&mut self) -> Result<u32, SessionError> {
        let mut b = [0; 4];
        self.fill(&mut b)?;
        Ok(u32::from_le_bytes(b))
    }

    pub(super) fn u64(&mut self) -> Result<u64, SessionError> {
        let mut b = [0; 8];
        self.fill(&mut b)?;
        Ok(u64::from_le_bytes(b))
    }

    pub(super) fn f32(&mut self) -> Result<f32, SessionError> {
        Ok(f32::from_bits(self.u32()?))
    }

    pub(super) fn f64(&mut self) -> Result<f64, SessionError> {
        Ok(f64::from_bits(self.u64()?))
    }

    /// A count that must not exceed `max` (what the configuration allows).
    pub(super) fn count(&mut self, max: usize, what: &str) -> Result<usize, SessionError> {
        let n = self.u64()?;
        usize::try_from(n)
            .ok()
            .filter(|&n| n <= max)
            .ok_or_else(|| {
                SessionError::Corrupt(format!("{}: {n} {what} (at most {max})", self.name))
            })
    }

    /// The bytes left in the entry (reading to its end checks the
    /// archive's checksum of it): an optional last field.
    pub(super) fn rest(mut self) -> Result<Vec<u8>, SessionError> {
        let mut rest = Vec::new();
        self.input
            .read_to_end(&mut rest)
            .map_err(|e| read_error(self.name, &e))?;
        Ok(rest)
    }

    /// Checks that the entry has no bytes left; reading to its end also
    /// checks the archive's checksum of it.
    pub(super) fn finish(mut self) -> Result<(), SessionError> {
        let mut rest = Vec::new();
        self.input
            .read_to_end(&mut rest)
            .map_err(|e| read_error(self.name, &e))?;
        if rest.is_empty() {
            Ok(())
        } else {
            Err(SessionError::Corrupt(format!(
                "{}: {} bytes after its end",
                self.name,
                rest.len()
            )))
        }
    }
}

/// An empty vector with room for `n` values, or an error naming `name`
/// when that much memory cannot be had (a damaged count).
pub(super) fn alloc<T>(n: usize, name: &str) -> Result<Vec<T>, SessionError> {
    let mut v = Vec::new();
    v.try_reserve_exact(n)
        .map_err(|_| SessionError::Corrupt(format!("{name}: {n} values do not fit in memory")))?;
    Ok(v)
}

/// The error of a failed read in entry `name`: its data ends early or
/// fails the archive's checksum.
pub(super) fn read_error(name: &str, e: &std::io::Error) -> SessionError {
    if e.kind() == std::io::ErrorKind::UnexpectedEof {
        SessionError::Corrupt(format!("{name} ends early"))
    } else {
        SessionError::Corrupt(format!("{name}: {e}"))
    }
}

/// Writes little-endian values.
pub(super) fn put_u32(out: &mut (impl Write + ?Sized), v: u32) -> std::io::Result<()> {
    out.write_all(&v.to_le_bytes())
}

pub(super) fn put_u64(out: &mut (impl Write + ?Sized), v: u64) -> std::io::Result<()> {
    out.write_all(&v.to_le_bytes())
}

pub(super) fn put_f32(out: &mut (impl Write + ?Sized), v: f32) -> std::io::Result<()> {
    out.write_all(&v.to_le_bytes())
}

pub(super) fn put_f64(out: &mut (impl Write + ?Sized), v: f64) -> std::io::Result<()> {
    out.write_all(&v.to_le_bytes())
}
