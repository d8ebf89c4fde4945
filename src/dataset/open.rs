//! Native filesystem access: listing a dataset folder, opening a [`Sequence`]
//! from it, and reading / decoding frames.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use super::{
    detect_layout, parse_pose_matrix, parse_sequence, DatasetError, DatasetKind, FrameEntry,
    Sequence,
};
use crate::frame::{Channel, DepthSettings, FrameError, RgbdFrame};

/// Lists `dir` recursively (3 levels: the sequence folder, an optional
/// wrapping folder, and `rgb/`-style sub-folders), names '/' separated and
/// relative to `dir`, hidden entries skipped, sorted.
pub fn list_files(dir: &Path) -> Result<Vec<String>, DatasetError> {
    fn walk(
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
                    walk(base, &child, depth - 1, out)?;
                }
            } else {
                out.push(child);
            }
        }
        Ok(())
    }
    let mut out = Vec::new();
    walk(dir, "", 2, &mut out)?;
    out.sort_unstable();
    Ok(out)
}

fn read_text(root: &Path, name: &str) -> Result<String, DatasetError> {
    let path = root.join(name);
    std::fs::read_to_string(&path).map_err(|e| DatasetError::Io {
        path: path.display().to_string(),
        message: e.to_string(),
    })
}

fn read_bytes(root: &Path, name: &str) -> Result<Vec<u8>, DatasetError> {
    let path = root.join(name);
    std::fs::read(&path).map_err(|e| DatasetError::Io {
        path: path.display().to_string(),
        message: e.to_string(),
    })
}

impl Sequence {
    /// Opens a dataset folder natively: lists it, detects the layout, reads the
    /// index files and (7-Scenes) every per-frame pose file. Frame paths are
    /// relative to `dir`; pass `dir` as `root` to [`read_frame`].
    pub fn open(dir: &Path) -> Result<Sequence, DatasetError> {
        let names = list_files(dir)?;
        let layout = detect_layout(&names)?;
        let mut texts = HashMap::new();
        for name in &layout.index_files {
            texts.insert(name.clone(), read_text(dir, name)?);
        }
        // The folder's own name (e.g. `rgbd_dataset_freiburg1_xyz`) picks the TUM camera.
        let absolute = dir.canonicalize().unwrap_or_else(|_| dir.to_path_buf());
        let hint = absolute
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let mut sequence = parse_sequence(&layout, &names, &texts, Some(&hint))?;
        if sequence.kind == DatasetKind::SevenScenes {
            let mut gt = Vec::new();
            for frame in &sequence.frames {
                if let Some(pose_file) = &frame.pose_file {
                    let pose = parse_pose_matrix(&read_text(dir, pose_file)?, pose_file)?;
                    gt.push((frame.timestamp, pose));
                }
            }
            sequence.ground_truth = gt;
        }
        Ok(sequence)
    }
}

/// Decodes a frame's colour and depth bytes (read by any means, e.g. in the
/// browser), naming the offending file in the error. Depth in metres per
/// `settings`.
pub fn decode_frame(
    entry: &FrameEntry,
    colour: &[u8],
    depth: &[u8],
    settings: &DepthSettings,
) -> Result<RgbdFrame, DatasetError> {
    RgbdFrame::from_png_bytes(colour, depth, settings).map_err(|source| {
        let path = match &source {
            FrameError::Decode {
                channel: Channel::Colour,
                ..
            }
            | FrameError::BufferLength {
                channel: Channel::Colour,
                ..
            } => entry.colour.clone(),
            FrameError::Decode {
                channel: Channel::Depth,
                ..
            }
            | FrameError::BufferLength {
                channel: Channel::Depth,
                ..
            }
            | FrameError::DepthNot16Bit { .. }
            | FrameError::InvalidDepth { .. } => entry.depth.clone(),
            _ => format!("{} + {}", entry.colour, entry.depth),
        };
        DatasetError::Frame { path, source }
    })
}

/// Reads and decodes one frame natively; `root` is the directory the
/// sequence was opened from. Depth in metres per `settings`.
pub fn read_frame(
    root: &Path,
    entry: &FrameEntry,
    settings: &DepthSettings,
) -> Result<RgbdFrame, DatasetError> {
    let colour = read_bytes(root, &entry.colour)?;
    let depth = read_bytes(root, &entry.depth)?;
    decode_frame(entry, &colour, &depth, settings)
}
