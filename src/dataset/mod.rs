//! RGB-D dataset loaders (TUM RGB-D, ICL-NUIM, Microsoft 7-Scenes, Intel
//! RealSense as Open3D's recorder writes it, iPhone LiDAR as the Stray
//! Scanner app exports it, a RealSense `.bag` recording: [`rosbag`]) and the
//! trajectory files (the surfel map's PLY file is in [`crate::mesh::surfel_ply`]).
//!
//! Parsing works in two pure steps on strings so that the browser (which only
//! has a list of file names and can read text files on request) and the native
//! CLI share it:
//!
//! 1. [`detect_layout`] looks at the file names and returns a [`Layout`]: the
//!    dataset kind and the small text files the parser needs.
//! 2. [`parse_sequence`] takes those texts and builds the [`Sequence`]: the
//!    frame list and, when present, the ground-truth trajectory.
//!
//! Paths: every path returned ([`Layout::index_files`], [`FrameEntry::colour`],
//! [`FrameEntry::depth`], [`FrameEntry::pose_file`]) is spelled exactly as in
//! the listing given to [`detect_layout`] (minus any leading `./`), '/'
//! separated, i.e. relative to the listing's root (the directory given to
//! [`Sequence::open`]). When every name shares a leading folder (a browser gives `teddy/rgb.txt`), that folder is
//! [`Layout::root_prefix`] and is already included in the returned paths.
//!
//! Poses are `world_from_camera` (camera-to-world, as the datasets publish
//! them), metres, timestamps in seconds (TUM, Stray Scanner) or frame
//! numbers (ICL-NUIM, 7-Scenes, RealSense).

pub mod archive;
pub mod db3;
mod decode;
mod error;
mod fields;
pub mod icl_nuim;
mod lines;
pub mod mkv;
mod open;
pub mod realsense;
pub mod reference;
pub mod rosbag;
pub mod seven_scenes;
pub mod stray;
pub mod trajectory;
pub mod tum;

use std::collections::HashMap;

use glam::DAffine3;

use crate::camera::{CameraPreset, Intrinsics};
use crate::imu::ImuSample;

pub use archive::{ArchiveFormat, ArchiveReader};
pub use decode::{decode_frame, decode_frame_bytes, FrameBytes, DEPTH_ONLY_GREY};
pub use error::DatasetError;
pub use open::{list_files, read_frame, DatasetSource};
pub use seven_scenes::parse_pose_matrix;

/// Which published dataset layout a folder follows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DatasetKind {
    /// TUM RGB-D: `rgb.txt`, `depth.txt`, optional `groundtruth.txt`.
    Tum,
    /// ICL-NUIM "frei_png": `associations.txt`, optional `*.gt.freiburg`.
    IclNuim,
    /// Microsoft 7-Scenes: `frame-NNNNNN.{color.png|color.jpg,depth.png,pose.txt}`,
    /// in `seq-XX/` folders or flat.
    SevenScenes,
    /// Intel RealSense as Open3D's `realsense_recorder.py` writes it:
    /// `color/NNNNNN.jpg` (or `.png`), `depth/NNNNNN.png`,
    /// `camera_intrinsic.json`.
    RealSense,
    /// iPhone / iPad LiDAR as the Stray Scanner app exports it:
    /// `depth/NNNNNN.png`, `confidence/NNNNNN.png`, `camera_matrix.csv`,
    /// `odometry.csv`, optional `rgb/NNNNNN.jpg` (frames extracted from
    /// `rgb.mp4`).
    StrayScanner,
    /// Intel RealSense as librealsense records it (RealSense Viewer,
    /// `rs-record`, up to 2.57): one ROS1 `.bag` file ([`rosbag`]),
    /// recognised by its first bytes.
    RealSenseBag,
    /// Intel RealSense as librealsense 2.58 and later records it: one
    /// ROS2 bag, an SQLite `.db3` file ([`db3`]), recognised by its first
    /// bytes.
    RealSenseDb3,
    /// Azure Kinect as `k4arecorder` records it: one Matroska `.mkv`
    /// file ([`mkv`]), recognised by its first bytes.
    AzureKinect,
}

impl DatasetKind {
    /// Short human-readable name (`TUM RGB-D`, `ICL-NUIM`, `7-Scenes`,
    /// `RealSense`, `Stray Scanner`, `RealSense .bag`, `RealSense .db3`,
    /// `Azure Kinect .mkv`).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Tum => "TUM RGB-D",
            Self::IclNuim => "ICL-NUIM",
            Self::SevenScenes => "7-Scenes",
            Self::RealSense => "RealSense",
            Self::StrayScanner => "Stray Scanner",
            Self::RealSenseBag => "RealSense .bag",
            Self::RealSenseDb3 => "RealSense .db3",
            Self::AzureKinect => "Azure Kinect .mkv",
        }
    }
}

/// Result of [`detect_layout`]: the dataset kind and the text files to read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Layout {
    /// The dataset layout recognised.
    pub kind: DatasetKind,
    /// Leading folder shared by every name (`""` or ending in `/`); already
    /// included in every path this module returns.
    pub root_prefix: String,
    /// Text files [`parse_sequence`] needs, full names as in the listing
    /// (TUM: rgb.txt, depth.txt, groundtruth.txt if present; ICL-NUIM: the
    /// associations file and the `*.gt.freiburg` if present; 7-Scenes: every
    /// per-frame `.pose.txt`, the ground truth, each optional; RealSense:
    /// `camera_intrinsic.json`; Stray Scanner: `camera_matrix.csv`,
    /// `odometry.csv` and, when listed, `imu.csv`).
    pub index_files: Vec<String>,
}

/// One RGB-D frame of a sequence: where its images (and pose) are.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameEntry {
    /// Position in the sequence, 0-based.
    pub index: usize,
    /// Seconds (TUM, the colour image's timestamp; Stray Scanner, the
    /// odometry's) or frame number (ICL-NUIM, 7-Scenes, RealSense).
    pub timestamp: f64,
    /// Colour image path, as in the listing; `None` for a depth-only
    /// sequence (Stray Scanner without an `rgb/` folder): the frame is
    /// decoded with a constant grey image.
    pub colour: Option<String>,
    /// Depth image path, as in the listing.
    pub depth: String,
    /// Per-pixel confidence image (Stray Scanner `confidence/NNNNNN.png`,
    /// 8-bit, 0 low, 1 medium, 2 high), as in the listing: depth whose
    /// confidence is 0 is dropped at decode.
    pub confidence: Option<String>,
    /// The depth image's size as the layout's calibration file gives it
    /// (RealSense, Stray Scanner): an image of another size is refused at
    /// decode ([`DatasetError::ImageSize`]). `None` for layouts whose camera
    /// is a preset.
    pub calibrated_size: Option<CalibratedSize>,
    /// Per-frame pose file (7-Scenes `.pose.txt`), as in the listing.
    pub pose_file: Option<String>,
    /// Why the frame cannot be read, known from the listing alone (an image
    /// its index names is absent: a half-copied dataset). Reading the frame
    /// returns this error, so it is skipped like an undecodable one.
    pub missing: Option<DatasetError>,
}

/// The image size a layout's calibration file gives, and that file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CalibratedSize {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// The file the size comes from (named in errors).
    pub file: String,
}

/// A parsed sequence: camera, frames in time order, ground truth if known.
#[derive(Debug, Clone, PartialEq)]
pub struct Sequence {
    /// The dataset layout.
    pub kind: DatasetKind,
    /// Camera calibration and depth conversion to use.
    pub preset: CameraPreset,
    /// The intrinsics of the depth images from the folder's own calibration
    /// file (RealSense `camera_intrinsic.json`; Stray Scanner
    /// `camera_matrix.csv` scaled from the colour camera's 1920x1440 to the
    /// depth's 256x192), pixels; they win over [`Self::preset`]'s. `None`
    /// for layouts whose camera is a preset.
    pub intrinsics: Option<Intrinsics>,
    /// Raw depth units per metre that the recording itself gives (a
    /// RealSense `.bag`'s depth units option: 1 / units); it wins over
    /// [`Self::preset`]'s. `None` for the layouts that say nothing.
    pub depth_scale: Option<f32>,
    /// Frames, in time order.
    pub frames: Vec<FrameEntry>,
    /// Ground truth `(timestamp, world_from_camera)`, sorted by timestamp,
    /// metres; empty when the dataset folder has none.
    pub ground_truth: Vec<(f64, DAffine3)>,
    /// The recording device's own trajectory `(timestamp, world_from_camera)`
    /// (Stray Scanner's `odometry.csv`, ARKit's visual-inertial odometry),
    /// sorted by timestamp, metres, camera axes as ours (x right, y down, z
    /// forward). Not ground truth: a reference to compare with, which
    /// drifts too. Empty for other layouts.
    pub odometry: Vec<(f64, DAffine3)>,
    /// The recording's IMU samples (Stray Scanner's `imu.csv`), in the
    /// file's order (seconds on the IMU's clock; device frame; m/s² with
    /// gravity, rad/s); empty when the recording has none. For
    /// [`crate::Pipeline::push_imu`].
    pub imu: Vec<ImuSample>,
    /// Problems that did not stop the sequence: a 7-Scenes pose file that
    /// could not be read (that frame has no ground truth), a cut-off last
    /// row of an index or trajectory file ([`DatasetError::CutOffLine`]:
    /// a recording stopped mid-write plays the rows it has).
    pub warnings: Vec<DatasetError>,
}

/// Frames and ground truth `(timestamp, world_from_camera)` parsed from index texts.
pub(crate) type Parsed = (Vec<FrameEntry>, Vec<(f64, DAffine3)>);

/// File name after the last '/'.
pub(crate) fn base_name(path: &str) -> &str {
    path.rsplit('/').next().unwrap_or(path)
}

/// Names in the listing that are not hidden (no component starting with '.').
fn visible(name: &str) -> bool {
    !name
        .split('/')
        .any(|c| c.starts_with('.') && c != "." && c != "..")
}

/// Longest leading folder shared by all names ("" or ending in '/').
fn common_prefix(names: &[&str]) -> String {
    let Some(first) = names.first() else {
        return String::new();
    };
    let mut prefix: Vec<&str> = first.split('/').collect();
    prefix.pop(); // the file name itself
    for name in &names[1..] {
        let mut parts: Vec<&str> = name.split('/').collect();
        parts.pop();
        let shared = prefix
            .iter()
            .zip(&parts)
            .take_while(|(a, b)| a == b)
            .count();
        prefix.truncate(shared);
    }
    prefix.iter().map(|c| format!("{c}/")).collect()
}

/// Recognises the dataset layout from a listing of file names ('/' separated,
/// relative to the folder chosen by the user; a shared leading folder is
/// allowed). Pure: no filesystem access.
pub fn detect_layout(file_names: &[String]) -> Result<Layout, DatasetError> {
    let names: Vec<&str> = file_names
        .iter()
        .map(|n| n.trim_start_matches("./"))
        .filter(|n| !n.is_empty() && visible(n))
        .collect();
    if names.is_empty() {
        return Err(DatasetError::EmptyFolder);
    }
    let root_prefix = common_prefix(&names);
    let top: Vec<&str> = names
        .iter()
        .filter_map(|n| n.strip_prefix(root_prefix.as_str()))
        .filter(|n| !n.contains('/'))
        .collect();
    let full = |n: &str| format!("{root_prefix}{n}");

    if top.contains(&"rgb.txt") && top.contains(&"depth.txt") {
        let mut index_files = vec![full("rgb.txt"), full("depth.txt")];
        if top.contains(&"groundtruth.txt") {
            index_files.push(full("groundtruth.txt"));
        }
        return Ok(Layout {
            kind: DatasetKind::Tum,
            root_prefix,
            index_files,
        });
    }
    let mut assoc: Vec<&str> = top
        .iter()
        .copied()
        .filter(|n| n.ends_with(".txt") && n.to_ascii_lowercase().contains("assoc"))
        .collect();
    if !assoc.is_empty() {
        assoc.sort_unstable();
        let mut index_files = vec![full(assoc[0])];
        let mut gt: Vec<&str> = top
            .iter()
            .copied()
            .filter(|n| n.ends_with(".gt.freiburg"))
            .collect();
        gt.sort_unstable();
        if let Some(g) = gt.first() {
            index_files.push(full(g));
        }
        return Ok(Layout {
            kind: DatasetKind::IclNuim,
            root_prefix,
            index_files,
        });
    }
    if names
        .iter()
        .any(|n| seven_scenes::colour_frame_number(base_name(n)).is_some())
    {
        let mut index_files: Vec<String> = names
            .iter()
            .filter(|n| seven_scenes::pose_frame_number(base_name(n)).is_some())
            .map(|n| (*n).to_owned())
            .collect();
        index_files.sort_unstable();
        return Ok(Layout {
            kind: DatasetKind::SevenScenes,
            root_prefix,
            index_files,
        });
    }
    if let Some(layout) = detect_sensor_layout(&top, &names, &root_prefix) {
        return Ok(layout);
    }
    let mut sample: Vec<&str> = names.iter().take(5).copied().collect();
    if names.len() > 5 {
        sample.push("...");
    }
    Err(DatasetError::UnknownLayout {
        hint: format!(
            "expected rgb.txt + depth.txt (TUM RGB-D), an associations .txt (ICL-NUIM) or \
             frame-NNNNNN.color.png or .color.jpg beside frame-NNNNNN.depth.png (7-Scenes; \
             in seq-XX/ folders or flat), camera_intrinsic.json + depth/NNNNNN.png (RealSense) \
             or camera_matrix.csv + odometry.csv + depth/NNNNNN.png (Stray Scanner); \
             found {} file(s): {}",
            names.len(),
            sample.join(", ")
        ),
    })
}

/// The layouts of a sensor's own recording tools, recognised by their
/// calibration files (`top`: the names directly in `root_prefix`) beside a
/// `depth/NNNNNN.png`: RealSense (Open3D's recorder) and Stray Scanner.
fn detect_sensor_layout(top: &[&str], names: &[&str], root_prefix: &str) -> Option<Layout> {
    let full = |n: &str| format!("{root_prefix}{n}");
    let (kind, index_files) = if top.contains(&"camera_intrinsic.json") {
        (DatasetKind::RealSense, vec![full("camera_intrinsic.json")])
    } else if top.contains(&"camera_matrix.csv") && top.contains(&"odometry.csv") {
        let mut files = vec![full("camera_matrix.csv"), full("odometry.csv")];
        if top.contains(&"imu.csv") {
            files.push(full("imu.csv"));
        }
        (DatasetKind::StrayScanner, files)
    } else {
        return None;
    };
    let has_depth = names.iter().any(|n| {
        n.strip_prefix(root_prefix)
            .and_then(|rest| rest.strip_prefix("depth/"))
            .is_some_and(|base| numbered(base, &["png"]).is_some())
    });
    has_depth.then(|| Layout {
        kind,
        root_prefix: root_prefix.to_owned(),
        index_files,
    })
}

/// Text of an index file named by the layout.
pub(crate) fn index_text<'a>(
    texts: &'a HashMap<String, String>,
    name: &str,
) -> Result<&'a str, DatasetError> {
    texts
        .get(name)
        .map(String::as_str)
        .ok_or_else(|| DatasetError::MissingFile {
            path: name.to_owned(),
            listed_in: "the index texts given to parse_sequence".to_owned(),
        })
}

/// Builds the frame list (and the ground truth when its file is in the layout)
/// from the listing and the texts of `layout.index_files` (keyed by those exact
/// names). `name_hint` (e.g. the folder name) helps pick the TUM camera
/// (`freiburg1`/`fr1`, ...; default fr3). Pure: no filesystem access.
///
/// An image named by an index (or, for 7-Scenes, the other image of a frame)
/// but absent from the listing does not refuse the sequence: that frame keeps
/// its place with [`FrameEntry::missing`] set. Only when no frame has all its
/// images is it an error ([`DatasetError::NoReadableFrame`]). 7-Scenes pose
/// texts are optional: a frame whose `.pose.txt` text is not given has no
/// ground truth.
pub fn parse_sequence(
    layout: &Layout,
    file_names: &[String],
    index_texts: &HashMap<String, String>,
    name_hint: Option<&str>,
) -> Result<Sequence, DatasetError> {
    let listing: std::collections::HashSet<&str> = file_names
        .iter()
        .map(|n| n.trim_start_matches("./"))
        .collect();
    let mut intrinsics = None;
    let mut odometry = Vec::new();
    let mut imu = Vec::new();
    let mut warnings = Vec::new();
    let (preset, frames, mut ground_truth) = match layout.kind {
        DatasetKind::Tum => {
            let (frames, gt) = tum::parse(layout, &listing, index_texts, &mut warnings)?;
            let hint_texts = [
                name_hint.unwrap_or(""),
                layout.root_prefix.as_str(),
                layout
                    .index_files
                    .first()
                    .and_then(|f| index_texts.get(f))
                    .map_or("", |t| {
                        t.lines()
                            .take_while(|l| l.trim_start().starts_with('#'))
                            .last()
                            .unwrap_or("")
                    }),
            ];
            (tum::preset_from_hints(&hint_texts), frames, gt)
        }
        DatasetKind::IclNuim => {
            let (frames, gt) = icl_nuim::parse(layout, &listing, index_texts, &mut warnings)?;
            (CameraPreset::IclNuim, frames, gt)
        }
        DatasetKind::SevenScenes => {
            let (frames, gt) = seven_scenes::parse(&listing, index_texts, &mut warnings)?;
            (CameraPreset::SevenScenes, frames, gt)
        }
        DatasetKind::RealSense => {
            let (k, frames) = realsense::parse(layout, &listing, index_texts)?;
            intrinsics = Some(k);
            (CameraPreset::RealSenseD400, frames, Vec::new())
        }
        DatasetKind::StrayScanner => {
            let parsed = stray::parse(layout, &listing, index_texts, &mut warnings)?;
            intrinsics = Some(parsed.intrinsics);
            odometry = parsed.odometry;
            imu = parsed.imu;
            (CameraPreset::StrayLidar, parsed.frames, Vec::new())
        }
        DatasetKind::RealSenseBag | DatasetKind::RealSenseDb3 | DatasetKind::AzureKinect => {
            return Err(DatasetError::UnknownLayout {
                hint: "a RealSense .bag or .db3 or an Azure Kinect .mkv is one file, read by its bytes \
                       (DatasetSource::open), not a listing of files"
                    .to_owned(),
            })
        }
    };
    if frames.is_empty() {
        return Err(DatasetError::NoFrames);
    }
    if let Some(first) = frames.iter().find_map(|f| f.missing.as_ref()) {
        if frames.iter().all(|f| f.missing.is_some()) {
            return Err(DatasetError::NoReadableFrame {
                frames: frames.len(),
                first: Box::new(first.clone()),
            });
        }
    }
    ground_truth.sort_by(|a, b| a.0.total_cmp(&b.0));
    odometry.sort_by(|a, b| a.0.total_cmp(&b.0));
    Ok(Sequence {
        kind: layout.kind,
        preset,
        intrinsics,
        depth_scale: None,
        frames,
        ground_truth,
        odometry,
        imu,
        warnings,
    })
}

/// [`DatasetError::MissingFile`] for `path` when the listing lacks it.
pub(crate) fn check_listed(
    listing: &std::collections::HashSet<&str>,
    path: &str,
    listed_in: &str,
) -> Option<DatasetError> {
    (!listing.contains(path)).then(|| DatasetError::MissingFile {
        path: path.to_owned(),
        listed_in: listed_in.to_owned(),
    })
}

/// Frame number of a name `NNNNNN.<ext>` (digits only before the dot, one
/// of `extensions`), as RealSense and Stray Scanner name their images.
pub(crate) fn numbered(file_name: &str, extensions: &[&str]) -> Option<u64> {
    let (digits, ext) = file_name.rsplit_once('.')?;
    if digits.is_empty()
        || !digits.bytes().all(|b| b.is_ascii_digit())
        || !extensions.iter().any(|e| e.eq_ignore_ascii_case(ext))
    {
        return None;
    }
    digits.parse().ok()
}

/// Frame number -> path of the images `NNNNNN.<ext>` directly in folder
/// `folder` (`root_prefix` + e.g. `depth/`), the first extension of
/// `extensions` winning when a number has several.
pub(crate) fn numbered_in<'a>(
    listing: &std::collections::HashSet<&'a str>,
    folder: &str,
    extensions: &[&str],
) -> std::collections::BTreeMap<u64, &'a str> {
    let mut out: std::collections::BTreeMap<u64, (usize, &str)> = Default::default();
    for &name in listing {
        let Some(rest) = name.strip_prefix(folder) else {
            continue;
        };
        if rest.contains('/') {
            continue;
        }
        let Some(n) = numbered(rest, extensions) else {
            continue;
        };
        let rank = rest
            .rsplit_once('.')
            .and_then(|(_, ext)| extensions.iter().position(|e| e.eq_ignore_ascii_case(ext)))
            .unwrap_or(usize::MAX);
        let slot = out.entry(n).or_insert((rank, name));
        if rank < slot.0 || (rank == slot.0 && name < slot.1) {
            *slot = (rank, name);
        }
    }
    out.into_iter().map(|(n, (_, name))| (n, name)).collect()
}

impl Sequence {
    /// Whether no frame has a colour image (Stray Scanner without `rgb/`):
    /// the frames decode with a constant grey image, so only geometry
    /// (ICP) can track them.
    #[must_use]
    pub fn is_depth_only(&self) -> bool {
        !self.frames.is_empty() && self.frames.iter().all(|f| f.colour.is_none())
    }

    /// Ground-truth `world_from_camera` nearest in time to `timestamp`, if one
    /// lies within `max_dt` (same unit as the timestamps; inclusive).
    #[must_use]
    pub fn ground_truth_for(&self, timestamp: f64, max_dt: f64) -> Option<DAffine3> {
        let gt = &self.ground_truth;
        let i = gt.partition_point(|(t, _)| *t < timestamp);
        [i.checked_sub(1), Some(i)]
            .into_iter()
            .flatten()
            .filter_map(|j| gt.get(j))
            .map(|(t, pose)| ((t - timestamp).abs(), pose))
            .filter(|(dt, _)| *dt <= max_dt)
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(_, pose)| *pose)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn listing(names: &[&str]) -> Vec<String> {
        names.iter().map(|s| (*s).to_owned()).collect()
    }

    #[test]
    fn empty_and_unknown_listings() {
        assert_eq!(detect_layout(&[]), Err(DatasetError::EmptyFolder));
        assert_eq!(
            detect_layout(&listing(&[".DS_Store"])),
            Err(DatasetError::EmptyFolder)
        );
        let err =
            detect_layout(&listing(&["photos/a.jpg", "photos/notes.txt"])).expect_err("unknown");
        match err {
            DatasetError::UnknownLayout { hint } => {
                assert!(
                    hint.contains("rgb.txt") && hint.contains("photos/a.jpg"),
                    "{hint}"
                );
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn shared_folder_and_hidden_files() {
        let names = listing(&[
            "teddy/rgb.txt",
            "teddy/depth.txt",
            ".DS_Store",
            "./teddy/rgb/1.png",
        ]);
        let layout = detect_layout(&names).expect("TUM");
        assert_eq!(layout.kind, DatasetKind::Tum);
        assert_eq!(layout.root_prefix, "teddy/");
        assert_eq!(layout.index_files, vec!["teddy/rgb.txt", "teddy/depth.txt"]);
        assert_eq!(DatasetKind::SevenScenes.name(), "7-Scenes");
    }
}
