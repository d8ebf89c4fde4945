//! Native filesystem access: listing a dataset folder (or an archive file),
//! opening a [`Sequence`] from it, and reading / decoding frames.

use std::collections::HashMap;
use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};

use super::archive::{self, ArchiveReader};
use super::db3::{self, RealSenseDb3};
use super::decode::{decode_frame_bytes, FrameBytes, DEPTH_ONLY_GREY};
use super::mkv::{self, AzureRecording};
use super::rosbag::{self, ImuSample, RawFrame, RealSenseBag};
use super::{detect_layout, parse_sequence, DatasetError, DatasetKind, FrameEntry, Sequence};
use crate::frame::{DepthSettings, RgbdFrame};

/// Lists `dir` recursively (3 levels: the sequence folder, an optional
/// wrapping folder, and `rgb/`-style sub-folders), names '/' separated and
/// relative to `dir`, hidden entries skipped, sorted.
pub fn list_files(dir: &Path) -> Result<Vec<String>, DatasetError> {
    fn walk_into(
        base: &Path,
        rel: &str,
        depth: usize,
        out: &mut Vec<String>,
    ) -> Result<(), DatasetError> {
        let here: PathBuf = if rel.is_empty() {
            base.to_path_buf()
        } else {
            base.join(rel)
        };
        let io = |e: std::io::Error| DatasetError::Io {
            path: here.display().to_string(),
            message: e.to_string(),
        };
        for entry in std::fs::read_dir(&here).map_err(io)? {
            let entry = entry.map_err(io)?;
            let name = entry.file_name().to_string_lossy().into_owned();
            if name.starts_with('.') {
                continue;
            }
            let child = if rel.is_empty() {
                name
            } else {
                format!("{rel}/{name}")
            };
            let kind = entry.file_type().map_err(io)?;
            // Follow symlinks: metadata() resolves them.
            let is_dir = kind.is_dir()
                || (kind.is_symlink()
                    && std::fs::metadata(base.join(&child)).is_ok_and(|m| m.is_dir()));
            if is_dir {
                if depth > 0 {
                    walk_into(base, &child, depth - 1, out)?;
                }
            } else {
                out.push(child);
            }
        }
        Ok(())
    }
    let mut out = Vec::new();
    walk_into(dir, "", 2, &mut out)?;
    out.sort_unstable();
    Ok(out)
}

fn read_bytes(root: &Path, name: &str) -> Result<Vec<u8>, DatasetError> {
    let path = root.join(name);
    std::fs::read(&path).map_err(|e| DatasetError::Io {
        path: path.display().to_string(),
        message: e.to_string(),
    })
}

impl Sequence {
    /// Opens a dataset natively, a folder, an archive file (`.zip`, `.tar`,
    /// `.tar.gz`/`.tgz`) or a recording (RealSense `.bag` or `.db3`, Azure
    /// Kinect `.mkv`; see [`DatasetSource`]): lists it, detects the layout,
    /// reads the index files (7-Scenes: the per-frame pose files). Frame paths
    /// are relative to `path`; for a folder pass `path` as `root` to
    /// [`read_frame`], for an archive read frames through a [`DatasetSource`].
    pub fn open(path: &Path) -> Result<Sequence, DatasetError> {
        DatasetSource::open(path)?.sequence()
    }
}

/// Where a dataset's files are read from natively: a folder, an archive
/// file read in place (never unpacked to disk), or a recording (RealSense
/// `.bag` or `.db3`, Azure `.mkv`: frames decoded from its messages, one
/// chunk or message in memory at a time).
pub enum DatasetSource {
    /// A dataset folder.
    Folder(PathBuf),
    /// An archive file and its reader.
    Archive {
        /// The archive file.
        path: PathBuf,
        /// Its contents, read on demand.
        reader: Box<ArchiveReader<File>>,
    },
    /// A RealSense recording (ROS1 bag), scanned once when opened.
    Bag {
        /// The bag file.
        path: PathBuf,
        /// The recording, read on demand.
        bag: Box<RealSenseBag<BufReader<File>>>,
    },
    /// A RealSense recording (ROS2 bag, SQLite `.db3`), scanned once when opened.
    Db3 {
        /// The .db3 file.
        path: PathBuf,
        /// The recording, read on demand.
        db3: Box<RealSenseDb3<BufReader<File>>>,
    },
    /// An Azure Kinect recording (Matroska), its structure read when opened.
    Mkv {
        /// The .mkv file.
        path: PathBuf,
        /// The recording, read on demand.
        mkv: Box<AzureRecording<BufReader<File>>>,
    },
}

impl DatasetSource {
    /// A folder, or a file read as a recording (`.bag`, `.db3`, `.mkv`) or an archive (its
    /// format sniffed from its first bytes, whatever its extension; errors
    /// name the file).
    pub fn open(path: &Path) -> Result<Self, DatasetError> {
        let io = |e: std::io::Error| DatasetError::Io {
            path: path.display().to_string(),
            message: e.to_string(),
        };
        if std::fs::metadata(path).map_err(io)?.is_dir() {
            return Ok(Self::Folder(path.to_path_buf()));
        }
        let mut head = Vec::with_capacity(16);
        File::open(path)
            .and_then(|f| f.take(16).read_to_end(&mut head))
            .map_err(io)?;
        if rosbag::is_rosbag(&head) {
            let file = File::open(path).map_err(io)?;
            let bag =
                RealSenseBag::open(BufReader::with_capacity(1 << 20, file)).map_err(|source| {
                    DatasetError::Rosbag {
                        path: path.display().to_string(),
                        source,
                    }
                })?;
            return Ok(Self::Bag {
                path: path.to_path_buf(),
                bag: Box::new(bag),
            });
        }
        if db3::is_sqlite(&head) {
            let file = File::open(path).map_err(io)?;
            // Pages are read in order where they can be: a small buffer
            // serves the overflow pages of one image without re-reading.
            let db3 =
                RealSenseDb3::open(BufReader::with_capacity(1 << 16, file)).map_err(|source| {
                    DatasetError::Db3 {
                        path: path.display().to_string(),
                        source,
                    }
                })?;
            return Ok(Self::Db3 {
                path: path.to_path_buf(),
                db3: Box::new(db3),
            });
        }
        if head.starts_with(&[0x1A, 0x45, 0xDF, 0xA3]) {
            let file = File::open(path).map_err(io)?;
            let mkv = AzureRecording::open(BufReader::with_capacity(1 << 20, file)).map_err(
                |source| DatasetError::Mkv {
                    path: path.display().to_string(),
                    source,
                },
            )?;
            return Ok(Self::Mkv {
                path: path.to_path_buf(),
                mkv: Box::new(mkv),
            });
        }
        let file = File::open(path).map_err(io)?;
        let reader = ArchiveReader::new(file, &path.display().to_string())?;
        Ok(Self::Archive {
            path: path.to_path_buf(),
            reader: Box::new(reader),
        })
    }

    /// Every file name, '/' separated, relative to the folder (or the
    /// archive's root).
    pub fn names(&self) -> Result<Vec<String>, DatasetError> {
        match self {
            Self::Folder(dir) => list_files(dir),
            Self::Archive { reader, .. } => Ok(reader.names().to_vec()),
            Self::Bag { path, .. } | Self::Db3 { path, .. } | Self::Mkv { path, .. } => {
                Ok(vec![path.display().to_string()])
            }
        }
    }

    /// The bytes of one file named as in [`Self::names`].
    pub fn read(&mut self, name: &str) -> Result<Vec<u8>, DatasetError> {
        match self {
            Self::Folder(dir) => read_bytes(dir, name),
            Self::Archive { reader, .. } => reader.read(name),
            Self::Bag { path, .. } | Self::Db3 { path, .. } | Self::Mkv { path, .. } => {
                Err(DatasetError::MissingFile {
                    path: name.to_owned(),
                    listed_in: format!("{} (a recording holds streams, not files)", path.display()),
                })
            }
        }
    }

    /// The folder's (or the archive's, without its extension) own name, e.g.
    /// `rgbd_dataset_freiburg1_xyz`: it picks the TUM camera.
    #[must_use]
    pub fn name_hint(&self) -> String {
        match self {
            Self::Folder(dir) => {
                let absolute = dir.canonicalize().unwrap_or_else(|_| dir.clone());
                absolute
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default()
            }
            Self::Bag { path, .. } | Self::Db3 { path, .. } | Self::Mkv { path, .. } => path
                .file_stem()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default(),
            Self::Archive { path, .. } => {
                let name = path
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default();
                archive::strip_archive_extension(&name).to_owned()
            }
        }
    }

    /// Detects the layout and parses the sequence. An optional file that
    /// cannot be read (a 7-Scenes pose file) becomes a warning, not an error,
    /// beside the parser's own ([`Sequence::warnings`]).
    pub fn sequence(&mut self) -> Result<Sequence, DatasetError> {
        if let Self::Bag { path, bag } = self {
            return Ok(rosbag::sequence_of(
                bag.recording(),
                &path.display().to_string(),
            ));
        }
        if let Self::Db3 { path, db3 } = self {
            return Ok(db3::sequence_of(
                db3.recording(),
                &path.display().to_string(),
            ));
        }
        if let Self::Mkv { path, mkv } = self {
            return Ok(mkv::sequence_of(mkv, &path.display().to_string()));
        }
        let names = self.names()?;
        let layout = detect_layout(&names)?;
        let optional = layout.kind == DatasetKind::SevenScenes;
        let mut texts = HashMap::new();
        let mut warnings = Vec::new();
        for name in &layout.index_files {
            match self.read(name).and_then(|bytes| text(name, bytes)) {
                Ok(t) => {
                    texts.insert(name.clone(), t);
                }
                Err(e) if optional => warnings.push(e),
                Err(e) => return Err(e),
            }
        }
        let mut sequence = parse_sequence(&layout, &names, &texts, Some(&self.name_hint()))?;
        // The files unread first, then what the parser skipped.
        warnings.append(&mut sequence.warnings);
        sequence.warnings = warnings;
        Ok(sequence)
    }

    /// Reads and decodes one frame (its [`FrameEntry::missing`] error if it
    /// has one). Depth in metres per `settings`.
    pub fn read_frame(
        &mut self,
        entry: &FrameEntry,
        settings: &DepthSettings,
    ) -> Result<RgbdFrame, DatasetError> {
        if let Self::Bag { .. } | Self::Db3 { .. } | Self::Mkv { .. } = self {
            let raw = self.read_raw(entry)?;
            let grey;
            let rgb = if raw.rgb.is_empty() {
                grey = vec![DEPTH_ONLY_GREY; 3 * raw.width * raw.height];
                &grey
            } else {
                &raw.rgb
            };
            return RgbdFrame::from_raw(raw.width, raw.height, rgb, &raw.depth, settings).map_err(
                |source| DatasetError::Frame {
                    path: entry.depth.clone(),
                    source,
                },
            );
        }
        read_entry(entry, settings, |name| self.read(name))
    }

    /// A `.bag`, `.db3` or `.mkv` frame's raw depth (the recording's units) and its colour
    /// registered to it (empty without [`FrameEntry::colour`]); for the
    /// other sources, [`DatasetError::MissingFile`] (their frames are files:
    /// [`Self::read`]).
    pub fn read_raw(&mut self, entry: &FrameEntry) -> Result<RawFrame, DatasetError> {
        match self {
            Self::Bag { path, bag } => {
                bag.read_frame(entry.index, entry.colour.is_some())
                    .map_err(|source| DatasetError::Rosbag {
                        path: format!("{}, {}", path.display(), entry.depth),
                        source,
                    })
            }
            Self::Db3 { path, db3 } => {
                db3.read_frame(entry.index, entry.colour.is_some())
                    .map_err(|source| DatasetError::Db3 {
                        path: format!("{}, {}", path.display(), entry.depth),
                        source,
                    })
            }
            Self::Mkv { path, mkv } => {
                mkv.read_frame(entry.index, entry.colour.is_some())
                    .map_err(|source| DatasetError::Mkv {
                        path: format!("{}, {}", path.display(), entry.depth),
                        source,
                    })
            }
            _ => Err(DatasetError::MissingFile {
                path: entry.depth.clone(),
                listed_in: "a folder or archive (its frames are image files)".to_owned(),
            }),
        }
    }

    /// The recording's IMU samples, in time order (a RealSense `.bag` or `.db3` with
    /// motion streams); empty for the other sources.
    #[must_use]
    pub fn imu(&self) -> &[ImuSample] {
        match self {
            Self::Bag { bag, .. } => &bag.recording().imu,
            Self::Db3 { db3, .. } => &db3.recording().imu,
            _ => &[],
        }
    }
}

fn text(name: &str, bytes: Vec<u8>) -> Result<String, DatasetError> {
    String::from_utf8(bytes).map_err(|_| DatasetError::Io {
        path: name.to_owned(),
        message: "not UTF-8 text".to_owned(),
    })
}

/// Reads and decodes one frame natively; `root` is the directory the
/// sequence was opened from. Depth in metres per `settings`.
pub fn read_frame(
    root: &Path,
    entry: &FrameEntry,
    settings: &DepthSettings,
) -> Result<RgbdFrame, DatasetError> {
    read_entry(entry, settings, |name| read_bytes(root, name))
}

/// Reads the files `entry` names through `read` and decodes them (its
/// [`FrameEntry::missing`] error if it has one).
fn read_entry(
    entry: &FrameEntry,
    settings: &DepthSettings,
    mut read: impl FnMut(&str) -> Result<Vec<u8>, DatasetError>,
) -> Result<RgbdFrame, DatasetError> {
    if let Some(e) = &entry.missing {
        return Err(e.clone());
    }
    let colour = entry.colour.as_deref().map(&mut read).transpose()?;
    let depth = read(&entry.depth)?;
    let confidence = entry.confidence.as_deref().map(&mut read).transpose()?;
    let bytes = FrameBytes {
        colour: colour.as_deref(),
        depth: &depth,
        confidence: confidence.as_deref(),
    };
    decode_frame_bytes(entry, &bytes, settings)
}
