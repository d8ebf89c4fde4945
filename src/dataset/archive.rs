//! Datasets packed in one archive file, read in place (never unpacked to
//! disk): `.zip`, `.tar` and `.tar.gz` / `.tgz`, the format sniffed from the
//! first bytes.
//!
//! - zip: random access through the central directory; each file is read
//!   (and inflated) when asked for.
//! - tar: one pass over the headers records where each file's bytes lie;
//!   each file is then read by seeking to them.
//! - tar.gz: gzip allows no seeking. One pass decompresses the archive to
//!   list its files (keeping the small non-image ones, e.g. index texts and
//!   pose files, in memory); frames are then read from a second stream in
//!   archive order. A file the stream passes before it is asked for is kept
//!   in memory until it is read (once); a file asked for after the stream
//!   passed it restarts the stream. Read frames in order and memory stays at
//!   the files the archive stores ahead of their turn.
//!
//! Names are '/' separated as stored, without a leading `./`; directories,
//! links and macOS `__MACOSX/` resource forks are left out.

use std::collections::{HashMap, HashSet};
use std::io::{self, BufReader, Read, Seek, SeekFrom};

use flate2::read::MultiGzDecoder;

use super::DatasetError;

/// Largest single file read from an archive, bytes: a forged size in a
/// header must not make us allocate gigabytes.
pub const MAX_FILE_BYTES: u64 = 1 << 30;

/// Non-image files up to this size are kept in memory by a tar.gz's listing
/// pass (index texts, 7-Scenes pose files, ground truth).
const KEEP_TEXT_BYTES: u64 = 64 << 20;

const BUFFER_BYTES: usize = 256 << 10;

/// An archive format this module reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ArchiveFormat {
    /// `.zip` (stored or deflated entries).
    Zip,
    /// Uncompressed `.tar` (ustar, GNU or pax).
    Tar,
    /// gzip-compressed tar (`.tar.gz`, `.tgz`).
    TarGz,
}

impl ArchiveFormat {
    /// Short name: `zip`, `tar`, `tar.gz`.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Zip => "zip",
            Self::Tar => "tar",
            Self::TarGz => "tar.gz",
        }
    }

    /// The format from a file's first bytes (at least 262 for tar), if known.
    #[must_use]
    pub fn sniff(head: &[u8]) -> Option<Self> {
        if head.starts_with(&[0x1f, 0x8b]) {
            Some(Self::TarGz)
        } else if head.starts_with(b"PK\x03\x04") || head.starts_with(b"PK\x05\x06") {
            Some(Self::Zip)
        } else if head.get(257..262) == Some(b"ustar") {
            Some(Self::Tar)
        } else {
            None
        }
    }
}

/// Whether a file name looks like an archive this module reads (by extension).
#[must_use]
pub fn is_archive_name(name: &str) -> bool {
    strip_archive_extension(name).len() < name.len()
}

/// `name` without a trailing `.zip`, `.tar`, `.tar.gz` or `.tgz` (any case).
#[must_use]
pub fn strip_archive_extension(name: &str) -> &str {
    let lower = name.to_ascii_lowercase();
    for ext in [".tar.gz", ".tgz", ".tar", ".zip"] {
        if lower.ends_with(ext) {
            return &name[..name.len() - ext.len()];
        }
    }
    name
}

/// Where a tar member's bytes lie in the (uncompressed) tar stream.
#[derive(Debug, Clone, Copy)]
struct Span {
    offset: u64,
    size: u64,
}

/// The decompressed tar stream of a tar.gz and how far it has been read.
struct GzStream<R> {
    decoder: MultiGzDecoder<BufReader<R>>,
    position: u64,
}

enum Inner<R: Read + Seek> {
    Zip(zip::ZipArchive<BufReader<R>>),
    Tar {
        reader: BufReader<R>,
        spans: HashMap<String, Span>,
        length: u64,
    },
    TarGz(Box<TarGz<R>>),
}

/// A tar.gz being read: see the module documentation.
struct TarGz<R> {
    /// The compressed file when no stream is open (a failed read drops the
    /// stream; the next read starts over).
    file: Option<BufReader<R>>,
    stream: Option<GzStream<R>>,
    spans: HashMap<String, Span>,
    /// `(offset, size, name)` by offset, to keep what the stream passes.
    order: Vec<(u64, u64, String)>,
    kept: HashMap<String, Vec<u8>>,
    taken: HashSet<String>,
}

/// A dataset archive opened for reading; see the module documentation.
pub struct ArchiveReader<R: Read + Seek> {
    path: String,
    format: ArchiveFormat,
    names: Vec<String>,
    inner: Inner<R>,
}

/// A member name as listed: '/' separated, no leading `./`; `None` for
/// names to leave out (macOS resource forks, empty).
fn clean_name(raw: &str) -> Option<String> {
    let name = raw.replace('\\', "/");
    let name = name.trim_start_matches("./").trim_start_matches('/');
    if name.is_empty() || name.ends_with('/') || name.split('/').any(|c| c == "__MACOSX") {
        return None;
    }
    Some(name.to_owned())
}

fn is_image(name: &str) -> bool {
    let lower = name.to_ascii_lowercase();
    [".png", ".jpg", ".jpeg"]
        .iter()
        .any(|ext| lower.ends_with(ext))
}

/// Reads exactly `size` bytes (at most [`MAX_FILE_BYTES`]) from `reader`.
fn read_exact_size(reader: &mut impl Read, size: u64) -> io::Result<Vec<u8>> {
    if size > MAX_FILE_BYTES {
        return Err(io::Error::new(
            io::ErrorKind::InvalidData,
            format!("a file of {size} bytes is larger than the {MAX_FILE_BYTES} bytes allowed"),
        ));
    }
    // No allocation by the claimed size: a truncated stream ends early.
    let mut out = Vec::new();
    reader.take(size).read_to_end(&mut out)?;
    if (out.len() as u64) < size {
        return Err(io::Error::new(
            io::ErrorKind::UnexpectedEof,
            "the archive ends in the middle of this file (truncated?)",
        ));
    }
    Ok(out)
}

/// Regular files of a tar with their spans, and the bytes of those kept.
type TarIndex = (Vec<(String, Span)>, HashMap<String, Vec<u8>>);

/// Lists a tar stream: each regular file's span, and (when `keep` says so)
/// its bytes.
fn index_tar(stream: impl Read, keep: impl Fn(&str, u64) -> bool) -> io::Result<TarIndex> {
    let mut archive = tar::Archive::new(stream);
    let mut spans = Vec::new();
    let mut kept = HashMap::new();
    for entry in archive.entries()? {
        let mut entry = entry?;
        let kind = entry.header().entry_type();
        if !(kind.is_file() || kind == tar::EntryType::Continuous) {
            continue;
        }
        let raw = String::from_utf8_lossy(&entry.path_bytes()).into_owned();
        let Some(name) = clean_name(&raw) else {
            continue;
        };
        let span = Span {
            offset: entry.raw_file_position(),
            size: entry.size(),
        };
        if keep(&name, span.size) {
            kept.insert(name.clone(), read_exact_size(&mut entry, span.size)?);
        }
        spans.push((name, span));
    }
    Ok((spans, kept))
}

impl<R: Read + Seek> ArchiveReader<R> {
    /// Opens an archive; `path` names it in errors. Reads the zip central
    /// directory or lists the tar (for tar.gz, decompressing it once).
    pub fn new(reader: R, path: &str) -> Result<Self, DatasetError> {
        let fail = |message: String| DatasetError::Archive {
            path: path.to_owned(),
            message,
        };
        let mut reader = BufReader::with_capacity(BUFFER_BYTES, reader);
        let mut head = Vec::with_capacity(512);
        (&mut reader)
            .take(512)
            .read_to_end(&mut head)
            .map_err(|e| fail(format!("cannot read: {e}")))?;
        reader
            .seek(SeekFrom::Start(0))
            .map_err(|e| fail(format!("cannot read: {e}")))?;
        if head.is_empty() {
            return Err(fail("the file is empty".to_owned()));
        }
        let Some(format) = ArchiveFormat::sniff(&head) else {
            return Err(fail(
                "not a .zip, .tar or .tar.gz archive (unknown signature)".to_owned(),
            ));
        };
        let corrupt = |e: &dyn std::fmt::Display| {
            fail(format!(
                "corrupt or truncated {} archive: {e}",
                format.name()
            ))
        };
        let (mut names, inner) = match format {
            ArchiveFormat::Zip => {
                let zip = zip::ZipArchive::new(reader).map_err(|e| corrupt(&e))?;
                let names: Vec<String> = zip.file_names().filter_map(clean_name).collect();
                (names, Inner::Zip(zip))
            }
            ArchiveFormat::Tar => {
                let length = reader
                    .seek(SeekFrom::End(0))
                    .and_then(|n| reader.seek(SeekFrom::Start(0)).map(|_| n))
                    .map_err(|e| fail(format!("cannot read: {e}")))?;
                let (list, _) = index_tar(&mut reader, |_, _| false).map_err(|e| corrupt(&e))?;
                if let Some((name, _)) = list.iter().find(|(_, s)| s.offset + s.size > length) {
                    return Err(corrupt(&format!(
                        "{name} ends past the end of the file (truncated?)"
                    )));
                }
                let names = list.iter().map(|(n, _)| n.clone()).collect();
                let spans = list.into_iter().collect();
                (
                    names,
                    Inner::Tar {
                        reader,
                        spans,
                        length,
                    },
                )
            }
            ArchiveFormat::TarGz => {
                let (list, kept) = index_tar(MultiGzDecoder::new(&mut reader), |name, size| {
                    !is_image(name) && size <= KEEP_TEXT_BYTES
                })
                .map_err(|e| corrupt(&e))?;
                let names = list.iter().map(|(n, _)| n.clone()).collect();
                let mut order: Vec<(u64, u64, String)> = list
                    .iter()
                    .map(|(n, s)| (s.offset, s.size, n.clone()))
                    .collect();
                order.sort_unstable();
                (
                    names,
                    Inner::TarGz(Box::new(TarGz {
                        file: Some(reader),
                        stream: None,
                        spans: list.into_iter().collect(),
                        order,
                        kept,
                        taken: HashSet::new(),
                    })),
                )
            }
        };
        names.sort_unstable();
        names.dedup();
        Ok(Self {
            path: path.to_owned(),
            format,
            names,
            inner,
        })
    }

    /// The archive's format.
    #[must_use]
    pub fn format(&self) -> ArchiveFormat {
        self.format
    }

    /// Every file in the archive, sorted.
    #[must_use]
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// The bytes of the file `name` (as in [`Self::names`]). Errors name the
    /// archive and the file.
    pub fn read(&mut self, name: &str) -> Result<Vec<u8>, DatasetError> {
        let path = &self.path;
        let fail = |e: &dyn std::fmt::Display| DatasetError::Archive {
            path: path.clone(),
            message: format!("{name}: {e}"),
        };
        let missing = || DatasetError::MissingFile {
            path: name.to_owned(),
            listed_in: format!("the archive {path}"),
        };
        match &mut self.inner {
            Inner::Zip(zip) => {
                let raw = zip
                    .file_names()
                    .find(|n| clean_name(n).as_deref() == Some(name))
                    .map(str::to_owned)
                    .ok_or_else(missing)?;
                let mut file = zip.by_name(&raw).map_err(|e| fail(&e))?;
                if file.size() > MAX_FILE_BYTES {
                    return Err(fail(&format!(
                        "a file of {} bytes is larger than the {MAX_FILE_BYTES} bytes allowed",
                        file.size()
                    )));
                }
                // Read to the entry's end (not just its size): the CRC is checked there.
                let mut out = Vec::new();
                (&mut file)
                    .take(MAX_FILE_BYTES + 1)
                    .read_to_end(&mut out)
                    .map_err(|e| fail(&e))?;
                if out.len() as u64 != file.size() {
                    return Err(fail(
                        &"the file's length differs from the archive's directory",
                    ));
                }
                Ok(out)
            }
            Inner::Tar {
                reader,
                spans,
                length,
            } => {
                let span = *spans.get(name).ok_or_else(missing)?;
                if span.offset + span.size > *length {
                    return Err(fail(&"the archive ends before this file does (truncated?)"));
                }
                reader
                    .seek(SeekFrom::Start(span.offset))
                    .and_then(|_| read_exact_size(reader, span.size))
                    .map_err(|e| fail(&e))
            }
            Inner::TarGz(gz) => {
                let TarGz {
                    file,
                    stream,
                    spans,
                    order,
                    kept,
                    taken,
                } = &mut **gz;
                let span = *spans.get(name).ok_or_else(missing)?;
                if let Some(bytes) = kept.remove(name) {
                    taken.insert(name.to_owned());
                    return Ok(bytes);
                }
                let result = read_gz(file, stream, span, order, kept, taken);
                if result.is_err() {
                    // Start over next time rather than read from a broken stream.
                    *stream = None;
                }
                let bytes = result.map_err(|e| fail(&e))?;
                taken.insert(name.to_owned());
                Ok(bytes)
            }
        }
    }
}

/// Reads `span` from the tar.gz stream, restarting it when `span` lies behind,
/// and keeps the files it passes on the way that were never read.
fn read_gz<R: Read + Seek>(
    file: &mut Option<BufReader<R>>,
    stream: &mut Option<GzStream<R>>,
    span: Span,
    order: &[(u64, u64, String)],
    kept: &mut HashMap<String, Vec<u8>>,
    taken: &HashSet<String>,
) -> io::Result<Vec<u8>> {
    if stream.as_ref().is_some_and(|s| s.position > span.offset) {
        if let Some(s) = stream.take() {
            *file = Some(s.decoder.into_inner());
        }
    }
    if stream.is_none() {
        let mut f = file
            .take()
            .ok_or_else(|| io::Error::other("the archive file was lost after an error"))?;
        f.seek(SeekFrom::Start(0))?;
        *stream = Some(GzStream {
            decoder: MultiGzDecoder::new(f),
            position: 0,
        });
    }
    let s = stream
        .as_mut()
        .ok_or_else(|| io::Error::other("no stream"))?;
    let first = order.partition_point(|(offset, _, _)| *offset < s.position);
    for (offset, size, name) in &order[first..] {
        if *offset >= span.offset {
            break;
        }
        if taken.contains(name) || kept.contains_key(name) {
            continue;
        }
        let size = *size;
        skip(&mut s.decoder, gap(s.position, *offset)?)?;
        s.position = *offset;
        let bytes = read_exact_size(&mut s.decoder, size)?;
        s.position += size;
        kept.insert(name.clone(), bytes);
    }
    skip(&mut s.decoder, gap(s.position, span.offset)?)?;
    s.position = span.offset;
    let bytes = read_exact_size(&mut s.decoder, span.size)?;
    s.position += span.size;
    Ok(bytes)
}

/// Bytes from `position` to `offset`; members never overlap in a tar the
/// listing accepted, so a negative gap is a corrupt archive.
fn gap(position: u64, offset: u64) -> io::Result<u64> {
    offset
        .checked_sub(position)
        .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidData, "overlapping tar members"))
}

fn skip(reader: &mut impl Read, n: u64) -> io::Result<()> {
    let skipped = io::copy(&mut reader.take(n), &mut io::sink())?;
    if skipped < n {
        return Err(io::Error::new(
            io::ErrorKind::UnexpectedEof,
            "the archive ends early (truncated?)",
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::{Cursor, Write};

    fn files() -> Vec<(String, Vec<u8>)> {
        (0..6)
            .map(|i| {
                let name = if i % 2 == 0 {
                    format!("seq/rgb/{i}.png")
                } else {
                    format!("seq/depth/{i}.png")
                };
                // Incompressible bytes: corrupting a zip entry must hit its data.
                let mut x = 0x9e37_79b9_u32.wrapping_mul(i as u32 + 1);
                let bytes = (0..700 + 1000 * i)
                    .map(|_| {
                        x ^= x << 13;
                        x ^= x >> 17;
                        x ^= x << 5;
                        x as u8
                    })
                    .collect();
                (name, bytes)
            })
            .chain([("seq/rgb.txt".to_owned(), b"0 rgb/0.png\n".to_vec())])
            .collect()
    }

    fn tar_bytes() -> Vec<u8> {
        let mut builder = tar::Builder::new(Vec::new());
        for (name, bytes) in files() {
            let mut header = tar::Header::new_gnu();
            header.set_size(bytes.len() as u64);
            header.set_mode(0o644);
            header.set_cksum();
            builder
                .append_data(&mut header, format!("./{name}"), bytes.as_slice())
                .expect("append");
        }
        builder.into_inner().expect("tar")
    }

    fn gz(bytes: &[u8]) -> Vec<u8> {
        let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        e.write_all(bytes).expect("gz");
        e.finish().expect("gz")
    }

    fn zip_bytes() -> Vec<u8> {
        let mut w = zip::ZipWriter::new(Cursor::new(Vec::new()));
        let options = zip::write::SimpleFileOptions::default()
            .compression_method(zip::CompressionMethod::Deflated);
        w.add_directory("seq/", options).expect("dir");
        for (name, bytes) in files() {
            w.start_file(name, options).expect("file");
            w.write_all(&bytes).expect("write");
        }
        w.start_file("__MACOSX/seq/._rgb.txt", options)
            .expect("fork");
        w.finish().expect("zip").into_inner()
    }

    fn check_all(bytes: Vec<u8>, format: ArchiveFormat) {
        let mut reader = ArchiveReader::new(Cursor::new(bytes), "a").expect("opens");
        assert_eq!(reader.format(), format);
        let mut expected: Vec<String> = files().into_iter().map(|f| f.0).collect();
        expected.sort();
        assert_eq!(reader.names(), expected.as_slice());
        // Backwards, then forwards, then one file twice: every access pattern.
        let all = files();
        for (name, bytes) in all.iter().rev().chain(all.iter()).chain(all.iter().take(1)) {
            assert!(&reader.read(name).expect(name) == bytes, "{name}");
        }
        let err = reader.read("seq/rgb/99.png").expect_err("absent");
        assert!(
            matches!(&err, DatasetError::MissingFile { path, .. } if path == "seq/rgb/99.png"),
            "{err:?}"
        );
    }

    #[test]
    fn every_format_lists_and_reads() {
        check_all(tar_bytes(), ArchiveFormat::Tar);
        check_all(gz(&tar_bytes()), ArchiveFormat::TarGz);
        check_all(zip_bytes(), ArchiveFormat::Zip);
    }

    #[test]
    fn corrupt_and_truncated_archives_are_errors() {
        let tar = tar_bytes();
        let tgz = gz(&tar);
        let zip = zip_bytes();
        let cases: Vec<(&str, Vec<u8>)> = vec![
            ("empty", Vec::new()),
            ("garbage", b"this is no archive".repeat(40)),
            ("truncated tar", tar[..tar.len() / 2].to_vec()),
            ("truncated tgz", tgz[..tgz.len() / 2].to_vec()),
            ("truncated zip", zip[..zip.len() - 30].to_vec()),
            ("gzip of garbage", gz(&b"not a tar".repeat(100))),
        ];
        for (what, bytes) in cases {
            let err = ArchiveReader::new(Cursor::new(bytes), "x.tgz").err();
            let err = err.unwrap_or_else(|| panic!("{what}: opened"));
            assert!(
                matches!(&err, DatasetError::Archive { path, .. } if path == "x.tgz"),
                "{what}: {err:?}"
            );
        }
        // Corrupt data inside a zip entry: that file fails, by name; the others read.
        let mut bad = zip.clone();
        let at = bad
            .windows(13)
            .position(|w| w == b"seq/rgb/4.png")
            .expect("local header")
            + 13
            + 100;
        for b in &mut bad[at..at + 40] {
            *b ^= 0x5a;
        }
        let mut reader = ArchiveReader::new(Cursor::new(bad), "x.zip").expect("directory intact");
        let err = reader.read("seq/rgb/4.png").expect_err("corrupt entry");
        assert!(err.to_string().contains("seq/rgb/4.png"), "{err}");
        assert!(reader.read("seq/rgb/2.png").is_ok());
    }

    #[test]
    fn extensions() {
        assert_eq!(strip_archive_extension("teddy.TGZ"), "teddy");
        assert_eq!(strip_archive_extension("a.b.tar.gz"), "a.b");
        assert!(is_archive_name("x.zip") && !is_archive_name("x.png"));
    }
}
