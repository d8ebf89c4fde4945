//! EBML, the binary format under Matroska: elements of an ID (a variable-
//! length integer kept with its length marker), a size (a variable-length
//! integer without it; all ones: unknown, "up to the parent's end") and
//! data. Read through `Read + Seek`; every size is checked against the
//! bytes left before anything is allocated for it.

use std::io::{Read, Seek, SeekFrom};

use super::MkvError;

/// An element's header as read at `pos`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Element {
    /// The element ID, with its length marker (`0x1A45DFA3`, `0xA3`, ...).
    pub id: u32,
    /// Where its data starts, bytes from the file's start.
    pub data_pos: u64,
    /// Its data's length, bytes; `None` for an unknown size.
    pub size: Option<u64>,
}

impl Element {
    /// The byte after the element, `parent_end` for an unknown size.
    pub(crate) fn end(&self, parent_end: u64) -> u64 {
        self.size.map_or(parent_end, |s| self.data_pos + s)
    }
}

fn io(e: &std::io::Error) -> MkvError {
    MkvError::Io(e.to_string())
}

/// Reads a variable-length integer at the reader's position: its value
/// (with the length marker when `keep_marker`, as IDs are written), its
/// length in bytes, and whether it is all ones (an unknown size).
fn vint<R: Read>(r: &mut R, keep_marker: bool, at: u64) -> Result<(u64, u64, bool), MkvError> {
    let mut first = [0u8; 1];
    r.read_exact(&mut first).map_err(|e| io(&e))?;
    let len = first[0].leading_zeros() + 1;
    if len > 8 {
        return Err(MkvError::Corrupt {
            offset: at,
            reason: "a variable-length integer of more than 8 bytes".to_owned(),
        });
    }
    let marker = 0x80u8 >> (len - 1);
    let mut value = u64::from(if keep_marker {
        first[0]
    } else {
        first[0] & marker.wrapping_sub(1)
    });
    let mut all_ones = first[0] & marker.wrapping_sub(1) == marker.wrapping_sub(1);
    for _ in 1..len {
        r.read_exact(&mut first).map_err(|e| io(&e))?;
        value = (value << 8) | u64::from(first[0]);
        all_ones &= first[0] == 0xff;
    }
    Ok((value, u64::from(len), all_ones))
}

/// Reads the element header at `pos` of a file of `file_len` bytes:
/// [`MkvError::Truncated`] when the header, or the data of known size,
/// runs past the file's end.
pub(crate) fn element<R: Read + Seek>(
    r: &mut R,
    pos: u64,
    file_len: u64,
) -> Result<Element, MkvError> {
    let e = header(r, pos, file_len)?;
    if e.size.is_some_and(|s| s > file_len - e.data_pos) {
        return Err(MkvError::Truncated { offset: pos });
    }
    Ok(e)
}

/// Reads the element header at `pos`, its data possibly running past the
/// file's end (a cut file's segment).
pub(crate) fn header<R: Read + Seek>(
    r: &mut R,
    pos: u64,
    file_len: u64,
) -> Result<Element, MkvError> {
    let truncated = || MkvError::Truncated { offset: pos };
    if pos + 2 > file_len {
        return Err(truncated());
    }
    r.seek(SeekFrom::Start(pos)).map_err(|e| io(&e))?;
    let (id, id_len, _) = vint(r, true, pos).map_err(|e| eof_is_truncation(e, pos))?;
    let (size, size_len, unknown) = vint(r, false, pos).map_err(|e| eof_is_truncation(e, pos))?;
    let data_pos = pos + id_len + size_len;
    let size = (!unknown).then_some(size);
    if data_pos > file_len {
        return Err(truncated());
    }
    Ok(Element {
        id: u32::try_from(id).map_err(|_| MkvError::Corrupt {
            offset: pos,
            reason: "an element ID of more than 4 bytes".to_owned(),
        })?,
        data_pos,
        size,
    })
}

fn eof_is_truncation(e: MkvError, pos: u64) -> MkvError {
    match e {
        MkvError::Io(_) => MkvError::Truncated { offset: pos },
        other => other,
    }
}

/// The data of `element` (of known size, at most `max` bytes).
pub(crate) fn data<R: Read + Seek>(
    r: &mut R,
    element: &Element,
    max: u64,
) -> Result<Vec<u8>, MkvError> {
    let size = element.size.ok_or(MkvError::Corrupt {
        offset: element.data_pos,
        reason: "a data element of unknown size".to_owned(),
    })?;
    if size > max {
        return Err(MkvError::Corrupt {
            offset: element.data_pos,
            reason: format!("an element of {size} bytes (at most {max} here)"),
        });
    }
    r.seek(SeekFrom::Start(element.data_pos))
        .map_err(|e| io(&e))?;
    let mut out = vec![0u8; size as usize];
    r.read_exact(&mut out).map_err(|e| io(&e))?;
    Ok(out)
}

/// An unsigned integer element's value (big-endian, at most 8 bytes).
pub(crate) fn uint(bytes: &[u8]) -> u64 {
    bytes
        .iter()
        .take(8)
        .fold(0u64, |v, &b| (v << 8) | u64::from(b))
}

/// A variable-length integer (without its marker) at the start of
/// `bytes`, and its length.
pub(crate) fn vint_in(bytes: &[u8]) -> Option<(u64, usize)> {
    let first = *bytes.first()?;
    let len = first.leading_zeros() as usize + 1;
    if len > 8 {
        return None;
    }
    let marker = 0x80u8 >> (len - 1);
    let rest = bytes.get(1..len)?;
    let value = rest
        .iter()
        .fold(u64::from(first & marker.wrapping_sub(1)), |v, &b| {
            (v << 8) | u64::from(b)
        });
    Some((value, len))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    #[test]
    fn variable_length_integers() {
        let mut c = Cursor::new(vec![
            0x1A, 0x45, 0xDF, 0xA3, 0x01, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF,
        ]);
        let e = element(&mut c, 0, 12).expect("reads");
        assert_eq!(
            (e.id, e.data_pos, e.size),
            (0x1A45_DFA3, 12, None),
            "8-byte unknown size"
        );
        let mut c = Cursor::new(vec![0xA3, 0x82, 0xAA, 0xBB]);
        let e = element(&mut c, 0, 4).expect("reads");
        assert_eq!((e.id, e.data_pos, e.size), (0xA3, 2, Some(2)));
        assert!(matches!(
            element(&mut c, 0, 3),
            Err(MkvError::Truncated { .. })
        ));
        assert_eq!(vint_in(&[0x81, 0x00]), Some((1, 1)));
        assert_eq!(vint_in(&[0x40, 0x02]), Some((2, 2)));
        assert_eq!(vint_in(&[0x00]), None);
        assert_eq!(vint_in(&[0x40]), None, "cut");
        assert_eq!(uint(&[0x03, 0xE8]), 1000);
    }
}
