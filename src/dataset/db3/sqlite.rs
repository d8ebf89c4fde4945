//! A read-only SQLite database file reader, as much of the public file
//! format (sqlite.org/fileformat.html) as a rosbag2 `.db3` needs: the
//! 100-byte header, table b-trees (interior and leaf pages), varints,
//! records, overflow pages, the schema table at page 1. Pages are read on
//! demand through `Read + Seek`; nothing is written, no journal or WAL is
//! replayed (a recording closed by its recorder has neither).
//!
//! Every page number, cell offset and length is checked against the page
//! or the file before use, and walks are bounded (tree depth, overflow
//! chain length), so a damaged file is an error, never a panic or a loop.

use std::io::{Read, Seek, SeekFrom};

use super::Db3Error;

/// The first 16 bytes of every SQLite 3 database file.
pub const MAGIC: &[u8; 16] = b"SQLite format 3\0";

/// The deepest b-tree walked: SQLite's own trees stay far below (a page
/// holds at least 4 children, so 20 levels is beyond any file size).
const MAX_DEPTH: usize = 20;

/// The longest record payload read whole, bytes (a 640x480 colour PNG is
/// under 1 MB; a raw 4K frame is 25 MB).
pub const MAX_PAYLOAD: u64 = 256 << 20;

/// A value of a record's column, as the file stores it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Value<'a> {
    /// NULL (an `INTEGER PRIMARY KEY` column holds NULL: its value is the rowid).
    Null,
    /// An integer.
    Int(i64),
    /// A float.
    Real(f64),
    /// Text, as stored (UTF-8 here).
    Text(&'a [u8]),
    /// A blob: its bytes within the payload read (possibly fewer than
    /// `full_len` when only a prefix of the payload was read).
    Blob {
        /// The bytes present.
        bytes: &'a [u8],
        /// The blob's whole length, bytes.
        full_len: u64,
    },
}

/// A table of the schema: its name, root page and `CREATE` statement.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Table {
    /// The table's name.
    pub name: String,
    /// Its b-tree's root page (1-based).
    pub root: u32,
    /// Its `CREATE TABLE` statement.
    pub sql: String,
}

/// A database file opened for reading; see the module documentation.
pub struct Sqlite<R> {
    reader: R,
    /// Where the reader stands, bytes (a seek is skipped when it is already there).
    pos: u64,
    page_size: usize,
    usable: usize,
    pages: u32,
    page: Vec<u8>,
    /// The page in `page` (0: none).
    current: u32,
}

/// A big-endian unsigned integer of `bytes` (at most 8).
fn be(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0, |v, &b| (v << 8) | u64::from(b))
}

/// A varint at `at` in `bytes`: its value and length, or `None` if cut off.
pub fn varint(bytes: &[u8], at: usize) -> Option<(u64, usize)> {
    let mut v = 0u64;
    for i in 0..9 {
        let b = *bytes.get(at + i)?;
        if i == 8 {
            return Some(((v << 8) | u64::from(b), 9));
        }
        v = (v << 7) | u64::from(b & 0x7f);
        if b & 0x80 == 0 {
            return Some((v, i + 1));
        }
    }
    None
}

/// The columns of a record (a table row's payload, or its first bytes:
/// a column past them is a [`Value::Blob`] or text cut short, or missing).
pub fn record(payload: &[u8]) -> Result<Vec<Value<'_>>, String> {
    let (header_len, n) = varint(payload, 0).ok_or("a record header cut off")?;
    let header_len = usize::try_from(header_len).map_err(|_| "a record header too long")?;
    if header_len < n || header_len > payload.len() {
        return Err(format!(
            "a record header of {header_len} bytes in {} bytes",
            payload.len()
        ));
    }
    let mut at = n;
    let mut body = header_len as u64;
    let mut out = Vec::new();
    while at < header_len {
        let (serial, n) = varint(payload, at).ok_or("a record header cut off")?;
        at += n;
        let len: u64 = match serial {
            0 | 8 | 9 => 0,
            1..=4 => serial,
            5 => 6,
            6 | 7 => 8,
            10 | 11 => return Err(format!("a reserved serial type {serial}")),
            _ => (serial - 12) / 2,
        };
        let start = usize::try_from(body).unwrap_or(usize::MAX);
        let end = usize::try_from(body.saturating_add(len)).unwrap_or(usize::MAX);
        let present = payload.get(start.min(payload.len())..end.min(payload.len()));
        let present = present.unwrap_or_default();
        let whole = present.len() as u64 == len;
        let value = match serial {
            0 => Value::Null,
            8 => Value::Int(0),
            9 => Value::Int(1),
            1..=6 if whole => {
                let bits = 8 * len as u32;
                let raw = be(present);
                // Sign-extend from the stored width.
                Value::Int(((raw << (64 - bits)) as i64) >> (64 - bits))
            }
            7 if whole => Value::Real(f64::from_bits(be(present))),
            s if s >= 12 && s % 2 == 0 => Value::Blob {
                bytes: present,
                full_len: len,
            },
            s if s >= 13 && whole => Value::Text(present),
            _ => return Err("a record cut off in a number or text column".to_owned()),
        };
        out.push(value);
        body = body.saturating_add(len);
    }
    Ok(out)
}

impl<R: Read + Seek> Sqlite<R> {
    /// Checks the header and reads the page size and count.
    pub fn open(mut reader: R) -> Result<Self, Db3Error> {
        let file_len = reader
            .seek(SeekFrom::End(0))
            .map_err(|e| Db3Error::Io(e.to_string()))?;
        let mut head = [0u8; 100];
        reader
            .seek(SeekFrom::Start(0))
            .and_then(|_| reader.read_exact(&mut head))
            .map_err(|_| Db3Error::NotSqlite)?;
        if &head[..16] != MAGIC {
            return Err(Db3Error::NotSqlite);
        }
        let page_size = match be(&head[16..18]) {
            1 => 65536,
            n if (512..=32768).contains(&n) && n.is_power_of_two() => n as usize,
            n => return Err(corrupt(0, format!("a page size of {n} bytes"))),
        };
        let reserved = usize::from(head[20]);
        let usable = page_size.saturating_sub(reserved);
        if usable < 480 {
            return Err(corrupt(0, format!("{usable} usable bytes a page")));
        }
        if be(&head[56..60]) > 1 {
            return Err(corrupt(
                0,
                "text not UTF-8 (UTF-16 databases are not read)".to_owned(),
            ));
        }
        // The header's page count holds when its change counter matches
        // the "version valid for" field; otherwise the file's length says.
        let from_len = u32::try_from(file_len / page_size as u64).unwrap_or(u32::MAX);
        let declared = be(&head[28..32]) as u32;
        let pages = if declared > 0 && head[24..28] == head[92..96] {
            declared
        } else {
            from_len
        };
        if u64::from(pages) * page_size as u64 > file_len {
            return Err(Db3Error::Truncated {
                what: format!(
                    "{pages} pages of {page_size} bytes declared, {file_len} bytes in the file"
                ),
            });
        }
        Ok(Self {
            reader,
            pos: 100,
            page_size,
            usable,
            pages,
            page: Vec::new(),
            current: 0,
        })
    }

    /// Pages in the database.
    #[must_use]
    pub fn pages(&self) -> u32 {
        self.pages
    }

    /// Reads page `n` (1-based) into `self.page`.
    fn load(&mut self, n: u32) -> Result<(), Db3Error> {
        if n == 0 || n > self.pages {
            return Err(corrupt(
                n,
                format!("a page number out of range (1 to {})", self.pages),
            ));
        }
        if self.current == n {
            return Ok(());
        }
        let at = u64::from(n - 1) * self.page_size as u64;
        self.current = 0;
        if self.pos != at {
            self.reader
                .seek(SeekFrom::Start(at))
                .map_err(|e| Db3Error::Io(e.to_string()))?;
        }
        self.page.resize(self.page_size, 0);
        self.pos = u64::MAX;
        self.reader.read_exact(&mut self.page).map_err(|e| {
            if e.kind() == std::io::ErrorKind::UnexpectedEof {
                Db3Error::Truncated {
                    what: format!("page {n}"),
                }
            } else {
                Db3Error::Io(e.to_string())
            }
        })?;
        self.pos = at + self.page_size as u64;
        self.current = n;
        Ok(())
    }

    /// The b-tree page `n`: its type, cells' offsets and right-most child.
    fn btree_page(&mut self, n: u32) -> Result<(u8, Vec<usize>, u32), Db3Error> {
        self.load(n)?;
        let base = if n == 1 { 100 } else { 0 };
        let p = &self.page;
        let kind = p[base];
        let interior = match kind {
            0x05 => true,
            0x0d => false,
            other => {
                return Err(corrupt(
                    n,
                    format!("not a table b-tree page (type {other:#04x})"),
                ));
            }
        };
        let cells = be(&p[base + 3..base + 5]) as usize;
        let header = if interior { 12 } else { 8 };
        let right = if interior {
            be(&p[base + 8..base + 12]) as u32
        } else {
            0
        };
        let pointers = p
            .get(base + header..base + header + 2 * cells)
            .ok_or_else(|| corrupt(n, format!("{cells} cells do not fit the page")))?;
        let offsets: Vec<usize> = pointers.chunks_exact(2).map(|c| be(c) as usize).collect();
        if let Some(bad) = offsets
            .iter()
            .find(|&&o| o < base + header || o >= self.usable)
        {
            return Err(corrupt(
                n,
                format!("a cell at byte {bad}, outside the page"),
            ));
        }
        Ok((kind, offsets, right))
    }

    /// The bytes of payload kept on a leaf page for a payload of `p` bytes.
    fn local_len(&self, p: u64) -> usize {
        let u = self.usable as u64;
        let x = u - 35;
        if p <= x {
            return p as usize;
        }
        let m = ((u - 12) * 32 / 255) - 23;
        let k = m + (p - m) % (u - 4);
        (if k <= x { k } else { m }) as usize
    }

    /// A leaf cell at `offset` of the page in memory: its rowid and the
    /// first `limit` bytes of its payload (following overflow pages as
    /// needed), and the payload's whole length.
    fn leaf_cell(
        &mut self,
        n: u32,
        offset: usize,
        limit: u64,
    ) -> Result<(i64, Vec<u8>, u64), Db3Error> {
        let cut = || corrupt(n, format!("the cell at byte {offset} is cut off"));
        let (len, a) = varint(&self.page, offset).ok_or_else(cut)?;
        let (rowid, b) = varint(&self.page, offset + a).ok_or_else(cut)?;
        let start = offset + a + b;
        let local = self.local_len(len);
        let want = len.min(limit);
        // A forged length must not allocate more than the file holds.
        let chunk = (self.usable - 4) as u64;
        let overflow_pages = len.saturating_sub(local as u64).div_ceil(chunk);
        if want > MAX_PAYLOAD || overflow_pages > u64::from(self.pages) {
            return Err(corrupt(n, format!("a row of {len} bytes")));
        }
        let mut out = Vec::with_capacity(want as usize);
        let here = self.page.get(start..start + local).ok_or_else(cut)?;
        out.extend_from_slice(&here[..here.len().min(want as usize)]);
        if (local as u64) < len && want > local as u64 {
            let next = self
                .page
                .get(start + local..start + local + 4)
                .ok_or_else(cut)?;
            let mut next = be(next) as u32;
            let chunk = self.usable - 4;
            // A chain longer than the payload needs is a loop.
            let mut left_pages = overflow_pages;
            while (out.len() as u64) < want {
                if left_pages == 0 {
                    return Err(corrupt(
                        n,
                        "an overflow chain longer than its payload".into(),
                    ));
                }
                left_pages -= 1;
                self.load(next)?;
                let take = chunk.min((want - out.len() as u64) as usize);
                out.extend_from_slice(&self.page[4..4 + take]);
                next = be(&self.page[..4]) as u32;
            }
        }
        Ok((rowid as i64, out, len))
    }

    /// Calls `visit(rowid, payload prefix, payload length)` for every row
    /// of the table whose root page is `root`, in rowid order, with at most
    /// `limit` bytes of each payload.
    pub fn for_each_row(
        &mut self,
        root: u32,
        limit: u64,
        mut visit: impl FnMut(i64, &[u8], u64) -> Result<(), Db3Error>,
    ) -> Result<(), Db3Error> {
        // Depth-first with an explicit stack of (page, depth); a page met
        // twice is a cycle.
        let mut stack = vec![(root, 0usize)];
        let mut seen = 0u64;
        while let Some((n, depth)) = stack.pop() {
            seen += 1;
            if depth > MAX_DEPTH || seen > u64::from(self.pages) {
                return Err(corrupt(n, "a b-tree deeper than the file (a cycle)".into()));
            }
            let (kind, cells, right) = self.btree_page(n)?;
            if kind == 0x05 {
                let mut children = Vec::with_capacity(cells.len() + 1);
                for &c in &cells {
                    let child = self
                        .page
                        .get(c..c + 4)
                        .ok_or_else(|| corrupt(n, "an interior cell cut off".into()))?;
                    children.push(be(child) as u32);
                }
                children.push(right);
                stack.extend(children.into_iter().rev().map(|c| (c, depth + 1)));
                continue;
            }
            for &c in &cells {
                // Overflow pages may have replaced the leaf in memory.
                self.load(n)?;
                let (rowid, payload, len) = self.leaf_cell(n, c, limit)?;
                visit(rowid, &payload, len)?;
            }
        }
        Ok(())
    }

    /// The whole payload of row `rowid` of the table at `root`, if present.
    pub fn row(&mut self, root: u32, rowid: i64) -> Result<Option<Vec<u8>>, Db3Error> {
        let mut n = root;
        for _ in 0..=MAX_DEPTH {
            let (kind, cells, right) = self.btree_page(n)?;
            if kind == 0x0d {
                for c in cells {
                    let cut = || corrupt(n, format!("the cell at byte {c} is cut off"));
                    let (_, a) = varint(&self.page, c).ok_or_else(cut)?;
                    let (id, _) = varint(&self.page, c + a).ok_or_else(cut)?;
                    if id as i64 == rowid {
                        return Ok(Some(self.leaf_cell(n, c, MAX_PAYLOAD)?.1));
                    }
                }
                return Ok(None);
            }
            // The first child whose key (its largest rowid) is >= rowid.
            let mut next = right;
            for c in cells {
                let cut = || corrupt(n, format!("the cell at byte {c} is cut off"));
                let child = self.page.get(c..c + 4).ok_or_else(cut)?;
                let (key, _) = varint(&self.page, c + 4).ok_or_else(cut)?;
                if rowid <= key as i64 {
                    next = be(child) as u32;
                    break;
                }
            }
            n = next;
        }
        Err(corrupt(n, "a b-tree deeper than the file (a cycle)".into()))
    }

    /// The tables of the schema (page 1).
    pub fn tables(&mut self) -> Result<Vec<Table>, Db3Error> {
        let mut tables = Vec::new();
        self.for_each_row(1, MAX_PAYLOAD, |_, payload, _| {
            let values = record(payload).map_err(|r| corrupt(1, format!("the schema: {r}")))?;
            if let [Value::Text(b"table"), Value::Text(name), _, Value::Int(root), sql, ..] =
                values.as_slice()
            {
                let sql = match sql {
                    Value::Text(s) => String::from_utf8_lossy(s).into_owned(),
                    _ => String::new(),
                };
                tables.push(Table {
                    name: String::from_utf8_lossy(name).into_owned(),
                    root: u32::try_from(*root).unwrap_or(0),
                    sql,
                });
            }
            Ok(())
        })?;
        Ok(tables)
    }
}

fn corrupt(page: u32, reason: String) -> Db3Error {
    Db3Error::Corrupt { page, reason }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn varints_and_records() {
        assert_eq!(varint(&[0x05], 0), Some((5, 1)));
        assert_eq!(varint(&[0x81, 0x00], 0), Some((128, 2)));
        assert_eq!(varint(&[0xff; 9], 0), Some((u64::MAX, 9)));
        assert_eq!(varint(&[0x81], 0), None);
        // Header: 5 bytes (len, NULL, i8, i16, blob of 2), body.
        let rec = [5u8, 0, 1, 2, 16, 0xfe, 0x01, 0x00, 0xaa, 0xbb];
        let v = record(&rec).expect("reads");
        assert_eq!(
            v,
            vec![
                Value::Null,
                Value::Int(-2),
                Value::Int(256),
                Value::Blob {
                    bytes: &[0xaa, 0xbb],
                    full_len: 2
                }
            ]
        );
        let cut = record(&rec[..9]).expect("a blob cut short reads");
        assert_eq!(
            cut[3],
            Value::Blob {
                bytes: &[0xaa],
                full_len: 2
            }
        );
        assert!(record(&rec[..6]).is_err(), "a number cut off");
        assert!(record(&[200]).is_err());
    }
}
