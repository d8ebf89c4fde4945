//! Session files: everything a [`Pipeline`] needs to go on where it
//! stopped, so that loading a session and pushing the next frames gives
//! exactly what an uninterrupted run gives (`tests/session.rs`).
//!
//! A session is a zip archive of open formats (the surfels stored, the rest deflated), one concern per
//! entry and per file here:
//!
//! | entry | holds | file |
//! |---|---|---|
//! | `manifest.json` | format name and version, camera, configuration, frame counter, verdict counts, last pose, loop-closure counters | `manifest.rs` |
//! | `surfels.ply` | every surfel with its times and confidence (binary PLY) | `surfels.rs` |
//! | `map_index.bin` | the map's block boxes and spatial order | `map_index.rs` |
//! | `keyframes.bin` | the fern keyframes (codes, small images, poses) | `keyframes.rs` |
//! | `trajectory.txt` | the trajectory, TUM text (for other tools) | `poses.rs` |
//! | `poses.txt` | the trajectory and the tracked one, exactly | `poses.rs` |
//! | `last_frame.bin` | what the next frames remember of the last fused one | `frame_memory.rs` |
//! | `camera_fixed.bin` | the last frame as the mask of things carried with the camera saw it, and what it masked (optional: older sessions start it afresh) | `camera_fixed.rs` |
//! | `lost_frame.bin` | while a segment begun by a restart after a long loss is not joined: the last frame placed before the loss (only then) | `frame_memory.rs` |
//! | `first_frame.bin` | the map's first frame as pushed, while a thing carried with the camera may still turn out to have been in it (only then) | `first_frame.rs` |
//!
//! Written and read an entry at a time, the surfels a row at a time: no
//! copy of the map's bytes is held. A file that is cut short, damaged,
//! written by a newer version or made with another camera is refused with
//! a [`SessionError`] saying which, and the pipeline loaded into is left as
//! it was.

mod binary;
mod camera_fixed;
mod error;
mod first_frame;
mod frame_memory;
mod keyframes;
mod manifest;
mod map_index;
mod poses;
mod surfels;

pub use error::SessionError;
pub use manifest::{Camera, Manifest};
pub use poses::{pose_from_rows, pose_to_rows};

use crate::dataset::trajectory::format_tum;
use crate::pipeline::{Pipeline, PipelineState};
use binary::LeReader;
use std::io::{BufReader, BufWriter, Read, Seek, SeekFrom, Write};
use zip::write::SimpleFileOptions;

/// The `format` of every session's manifest.
pub const FORMAT: &str = "surfel-slam session";
/// The newest format version this build writes and reads.
pub const FORMAT_VERSION: u32 = 1;

const MANIFEST: &str = "manifest.json";
const SURFELS: &str = "surfels.ply";
const MAP_INDEX: &str = "map_index.bin";
const KEYFRAMES: &str = "keyframes.bin";
const TRAJECTORY: &str = "trajectory.txt";
const POSES: &str = "poses.txt";
use first_frame::FIRST_FRAME;
use frame_memory::{LAST_FRAME, LOST_FRAME};
const CAMERA_FIXED: &str = "camera_fixed.bin";

/// Largest manifest read, bytes.
const MAX_MANIFEST: u64 = 16 << 20;

/// Writes `pipeline`'s session to `out`; returns `out`. Refused in
/// localise mode ([`SessionError::Localising`]).
pub fn save<W: Write + Seek>(pipeline: &Pipeline, out: W) -> Result<W, SessionError> {
    if pipeline.is_localising() {
        return Err(SessionError::Localising);
    }
    let state = pipeline.state();
    let failed = |e: &dyn std::fmt::Display| SessionError::Write(e.to_string());
    let mut zip = zip::ZipWriter::new(out);
    // Level 1: the fast level keeps saving quick.
    let options = SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated)
        .compression_level(Some(1))
        .large_file(true);
    let mut entry = |name: &str,
                     write: &mut dyn FnMut(&mut dyn Write) -> std::io::Result<()>|
     -> Result<(), SessionError> {
        // The surfels are float bits, which deflate shrinks by 8 % at
        // four times the saving time (kitchen, 1.4 M surfels): stored.
        let options = if name == SURFELS {
            options
                .compression_method(zip::CompressionMethod::Stored)
                .compression_level(None)
        } else {
            options
        };
        zip.start_file(name, options).map_err(|e| failed(&e))?;
        let mut buffered = BufWriter::with_capacity(1 << 16, &mut zip);
        write(&mut buffered).map_err(|e| failed(&e))?;
        buffered.flush().map_err(|e| failed(&e))
    };
    let manifest = Manifest::of(&state);
    entry(MANIFEST, &mut |w| {
        serde_json::to_writer_pretty(&mut *w, &manifest).map_err(std::io::Error::other)?;
        writeln!(w)
    })?;
    entry(SURFELS, &mut |w| surfels::write_surfels(w, state.map))?;
    entry(MAP_INDEX, &mut |w| {
        map_index::write_map_index(w, state.map, state.runs)
    })?;
    let ferns = state.config.relocalise.ferns;
    entry(KEYFRAMES, &mut |w| {
        keyframes::write_keyframes(w, state.keyframes, &ferns)
    })?;
    entry(TRAJECTORY, &mut |w| {
        w.write_all(format_tum(state.trajectory).as_bytes())
    })?;
    entry(POSES, &mut |w| {
        poses::write_poses(w, state.trajectory, state.online_trajectory)
    })?;
    entry(LAST_FRAME, &mut |w| {
        frame_memory::write_frame_memory(w, state.last_fused.as_ref(), &state.photometric)
    })?;
    entry(CAMERA_FIXED, &mut |w| {
        camera_fixed::write_camera_fixed(w, state.camera_fixed)
    })?;
    if let Some(lost) = &state.lost_frame {
        entry(LOST_FRAME, &mut |w| {
            frame_memory::write_frame_memory(w, Some(lost), &[])
        })?;
    }
    if let Some(first) = state.first_frame {
        entry(FIRST_FRAME, &mut |w| {
            first_frame::write_first_frame(w, first)
        })?;
    }
    zip.finish().map_err(|e| failed(&e))
}

/// Reads a session into a new pipeline (its configuration and camera are
/// the session's).
pub fn load<R: Read + Seek>(input: R) -> Result<Pipeline, SessionError> {
    read(input, None)
}

/// Reads a session made with `pipeline`'s camera and replaces `pipeline`
/// by it (its configuration becomes the session's). On any error
/// `pipeline` is left as it was.
pub fn load_into<R: Read + Seek>(pipeline: &mut Pipeline, input: R) -> Result<(), SessionError> {
    let camera = Camera::of(pipeline.config());
    *pipeline = read(input, Some(&camera))?;
    Ok(())
}

/// Reads only the manifest of a session (what it is, its camera and counters).
pub fn read_manifest<R: Read + Seek>(input: R) -> Result<Manifest, SessionError> {
    let mut zip = open_archive(input)?;
    manifest_of(&mut zip)
}

fn manifest_of<R: Read + Seek>(zip: &mut zip::ZipArchive<R>) -> Result<Manifest, SessionError> {
    let mut bytes = Vec::new();
    let file = zip.by_name(MANIFEST).map_err(|e| match e {
        zip::result::ZipError::FileNotFound => {
            SessionError::NotASession(format!("a zip archive without {MANIFEST}"))
        }
        e => SessionError::Corrupt(format!("{MANIFEST}: {e}")),
    })?;
    file.take(MAX_MANIFEST)
        .read_to_end(&mut bytes)
        .map_err(|e| binary::read_error(MANIFEST, &e))?;
    Manifest::parse(&bytes)
}

/// Opens the archive, telling a file cut short (its table of contents,
/// at the end, missing) from a damaged one and from another kind of file.
fn open_archive<R: Read + Seek>(mut input: R) -> Result<zip::ZipArchive<R>, SessionError> {
    let opened = zip::ZipArchive::new(&mut input);
    let error = match opened {
        Ok(_) => None,
        Err(e) => Some(e.to_string()),
    };
    let Some(error) = error else {
        input
            .rewind()
            .map_err(|e| SessionError::Corrupt(e.to_string()))?;
        return zip::ZipArchive::new(input).map_err(|e| SessionError::Corrupt(e.to_string()));
    };
    let read_err = |e: std::io::Error| SessionError::Corrupt(e.to_string());
    let len = input.seek(SeekFrom::End(0)).map_err(read_err)?;
    input.rewind().map_err(read_err)?;
    let mut start = [0u8; 4];
    if len < 4 || input.read_exact(&mut start).is_err() || &start != b"PK\x03\x04" {
        return Err(SessionError::NotASession(format!(
            "{len} bytes that do not start as a zip archive"
        )));
    }
    // The end-of-archive record lies within the last 22 + 65535 bytes.
    let tail_len = len.min(22 + 65535);
    input
        .seek(SeekFrom::Start(len - tail_len))
        .map_err(read_err)?;
    let mut tail = Vec::new();
    input
        .take(tail_len)
        .read_to_end(&mut tail)
        .map_err(read_err)?;
    // The record is 22 bytes and its comment, to the file's end.
    let record = tail.windows(4).rposition(|w| w == b"PK\x05\x06");
    let whole = record.is_some_and(|at| {
        let r = &tail[at..];
        r.len() >= 22 && r.len() >= 22 + usize::from(u16::from_le_bytes([r[20], r[21]]))
    });
    if !whole {
        return Err(SessionError::Truncated(format!(
            "it ends after {len} bytes, before the archive's table of contents (was it copied completely?)"
        )));
    }
    Err(SessionError::Corrupt(error))
}

/// Entry `name` of the archive, buffered.
fn entry<'a, R: Read + Seek>(
    zip: &'a mut zip::ZipArchive<R>,
    name: &'static str,
) -> Result<BufReader<zip::read::ZipFile<'a, R>>, SessionError> {
    zip.by_name(name)
        .map(|f| BufReader::with_capacity(1 << 16, f))
        .map_err(|e| SessionError::Corrupt(format!("{name}: {e}")))
}

fn read<R: Read + Seek>(input: R, camera: Option<&Camera>) -> Result<Pipeline, SessionError> {
    let mut zip = open_archive(input)?;
    let manifest = manifest_of(&mut zip)?;
    if let Some(difference) = camera.and_then(|c| manifest.camera.difference(c)) {
        return Err(SessionError::CameraMismatch(difference));
    }
    let corrupt = |name: &str, e: String| SessionError::Corrupt(format!("{name}: {e}"));
    let mut map = {
        let mut input = entry(&mut zip, SURFELS)?;
        let map = surfels::read_surfels(&mut input, manifest.surfels)?;
        LeReader::new(input, SURFELS).finish()?;
        map
    };
    let (blocks, runs) = map_index::read_map_index(entry(&mut zip, MAP_INDEX)?, map.len())?;
    map.finish_restore(blocks, manifest.schedule())
        .map_err(|e| corrupt(SURFELS, e))?;
    let config = manifest.config.clone();
    let keyframes = keyframes::read_keyframes(
        entry(&mut zip, KEYFRAMES)?,
        manifest.keyframes,
        &config.relocalise.ferns,
    )?;
    let (trajectory, online_trajectory) =
        poses::read_poses(entry(&mut zip, POSES)?, manifest.frames as usize)?;
    let working = config.working_intrinsics();
    let (last_fused, photometric) = frame_memory::read_frame_memory(
        entry(&mut zip, LAST_FRAME)?,
        (LAST_FRAME, working.pixel_count()),
    )?;
    let lost_frame = match zip.by_name(LOST_FRAME) {
        Err(zip::result::ZipError::FileNotFound) => None,
        Err(e) => return Err(corrupt(LOST_FRAME, e.to_string())),
        Ok(file) => {
            frame_memory::read_frame_memory(
                BufReader::new(file),
                (LOST_FRAME, working.pixel_count()),
            )?
            .0
        }
    };
    let input_pixels = config.intrinsics.pixel_count();
    let camera_fixed = match zip.by_name(CAMERA_FIXED) {
        Err(zip::result::ZipError::FileNotFound) => Default::default(),
        Err(e) => return Err(corrupt(CAMERA_FIXED, e.to_string())),
        Ok(file) => camera_fixed::read_camera_fixed(
            BufReader::new(file),
            input_pixels,
            config.preprocess.camera_fixed_frames,
        )?,
    };
    let first_frame = match zip.by_name(FIRST_FRAME) {
        Err(zip::result::ZipError::FileNotFound) => None,
        Err(e) => return Err(corrupt(FIRST_FRAME, e.to_string())),
        Ok(file) => Some(first_frame::read_first_frame(
            BufReader::new(file),
            (config.intrinsics.width, config.intrinsics.height),
        )?),
    };
    Pipeline::from_state(PipelineState {
        config,
        scalars: manifest.scalars(),
        map,
        runs,
        trajectory,
        online_trajectory,
        keyframes,
        last_fused,
        photometric,
        camera_fixed,
        lost_frame,
        first_frame,
    })
    .map_err(|e| SessionError::Corrupt(e.to_string()))
}
