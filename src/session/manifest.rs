//! `manifest.json`: what the session is (format name and version), the
//! camera, the configuration and the pipeline's counters. Read first: a
//! file of a newer version, or for another camera, is refused before the
//! map is read.

use super::poses::{pose_from_rows, pose_to_rows};
use super::{SessionError, FORMAT, FORMAT_VERSION};
use crate::camera::Intrinsics;
use crate::frame::DepthSettings;
use crate::fusion::MapSchedule;
use crate::noise::SensorNoise;
use crate::pipeline::{PipelineScalars, Segment, SlamConfig, StateView, VerdictCounts};
use serde::{Deserialize, Serialize};

/// The two fields every version has: read before the rest.
#[derive(Debug, Deserialize)]
struct Header {
    format: String,
    version: u32,
}

/// The camera a session was made with: frames pushed after loading must
/// come from the same one.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Camera {
    /// Intrinsics at the input resolution.
    pub intrinsics: Intrinsics,
    /// Raw depth to metres.
    pub depth: DepthSettings,
}

impl Camera {
    /// The camera of `config`.
    #[must_use]
    pub fn of(config: &SlamConfig) -> Self {
        Self {
            intrinsics: config.intrinsics,
            depth: config.depth,
        }
    }

    /// The first value in which `saved` (this session's) differs from the
    /// camera in use, as `name saved X, in use Y`; `None` when they agree.
    #[must_use]
    pub fn difference(&self, in_use: &Camera) -> Option<String> {
        let (a, b) = (&self.intrinsics, &in_use.intrinsics);
        let (da, db) = (&self.depth, &in_use.depth);
        let values = [
            ("width", a.width as f64, b.width as f64),
            ("height", a.height as f64, b.height as f64),
            ("fx", a.fx.into(), b.fx.into()),
            ("fy", a.fy.into(), b.fy.into()),
            ("cx", a.cx.into(), b.cx.into()),
            ("cy", a.cy.into(), b.cy.into()),
            ("depth scale", da.scale.into(), db.scale.into()),
            ("depth min", da.min_m.into(), db.min_m.into()),
            ("depth max", da.max_m.into(), db.max_m.into()),
        ];
        if let Some((name, s, u)) = values.iter().find(|(_, s, u)| s.to_bits() != u.to_bits()) {
            return Some(format!("{name} {s} in the session, {u} in use"));
        }
        (da.invalid_raw != db.invalid_raw).then(|| {
            format!(
                "invalid raw depth {:?} in the session, {:?} in use",
                da.invalid_raw, db.invalid_raw
            )
        })
    }
}

/// The manifest: see the module documentation. Poses are
/// `world_from_camera` as 12 numbers, row-major 3x4 (metres).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// Always [`FORMAT`].
    pub format: String,
    /// [`FORMAT_VERSION`] when written by this build.
    pub version: u32,
    /// The program that wrote it (name and version).
    pub writer: String,
    /// The camera (also in `config`; here for readers of the manifest).
    pub camera: Camera,
    /// The pipeline's configuration (noise models as chosen at frame 0).
    pub config: SlamConfig,
    /// Tracker and fusion noise models as configured before frame 0.
    pub configured_noise: [SensorNoise; 2],
    /// Frames accepted (the next frame's index).
    pub frames: u32,
    /// Verdict counts `[tracked, lost, recovered, held, lost_streak]`.
    pub counts: [u32; 5],
    /// Frames that restarted the map after a long loss (absent in sessions
    /// saved before restarts: none).
    #[serde(default)]
    pub restarted: u32,
    /// The map's current segment `[first frame, frames fused before it]`
    /// (absent in sessions saved before restarts: `[0, 0]`, the first
    /// segment).
    #[serde(default)]
    pub segment: [u32; 2],
    /// Pose of the last placed frame (fused, or dead-reckoned while lost).
    pub last_good: Option<[f64; 12]>,
    /// Index of that frame (absent in sessions saved before dead
    /// reckoning: the last fused one).
    #[serde(default)]
    pub placed_frame: Option<u32>,
    /// Index of the last fused frame measured in every direction, not
    /// held (absent in sessions saved before it was kept).
    #[serde(default)]
    pub measured_frame: Option<u32>,
    /// Motion of the last two fused frames in a row (`previous_from_current`).
    pub velocity: Option<[f64; 12]>,
    /// `[first anchored frame, last frame to try]` while the camera is to
    /// be placed again after a carried thing was masked (absent: none).
    #[serde(default)]
    pub anchored: Option<[u32; 2]>,
    /// Loop closures so far.
    pub loop_closures: u32,
    /// Of those, the global ones.
    pub global_loop_closures: u32,
    /// Frame of the last global closure (its cooldown).
    pub last_global_closure: Option<u32>,
    /// The first depth image was checked against the depth settings.
    pub depth_checked: bool,
    /// Surfel slots in `surfels.ply` (absorbed ones included).
    pub surfels: usize,
    /// Frame of the last removal of unstable surfels.
    pub last_cleanup: Option<u32>,
    /// Lowest slot absorbed since then.
    pub first_absorbed: Option<usize>,
    /// Absorbed slots awaiting removal.
    pub absorbed: usize,
    /// Keyframes in `keyframes.bin`.
    pub keyframes: usize,
}

impl Manifest {
    /// The manifest of a pipeline's state.
    #[must_use]
    pub fn of(state: &StateView<'_>) -> Self {
        let s = &state.scalars;
        let c = s.counts;
        let schedule = state.map.schedule();
        Self {
            format: FORMAT.into(),
            version: FORMAT_VERSION,
            writer: format!("surfel-slam {}", env!("CARGO_PKG_VERSION")),
            camera: Camera::of(state.config),
            config: state.config.clone(),
            configured_noise: [s.configured_noise.0, s.configured_noise.1],
            frames: s.frames,
            counts: [c.tracked, c.lost, c.recovered, c.held, c.lost_streak],
            restarted: c.restarted,
            segment: [s.segment.start, s.segment.fused_before],
            last_good: s.last_good.as_ref().map(pose_to_rows),
            placed_frame: s.placed_frame,
            measured_frame: s.measured_frame,
            velocity: s.velocity.as_ref().map(pose_to_rows),
            anchored: s.anchored,
            loop_closures: s.loop_counters.0,
            global_loop_closures: s.loop_counters.1,
            last_global_closure: s.loop_counters.2,
            depth_checked: s.depth_checked,
            surfels: state.map.len(),
            last_cleanup: schedule.last_cleanup,
            first_absorbed: schedule.first_absorbed,
            absorbed: schedule.absorbed,
            keyframes: state.keyframes.len(),
        }
    }

    /// Parses the manifest; a newer version is refused before its fields
    /// are read (they may have changed).
    pub fn parse(bytes: &[u8]) -> Result<Self, SessionError> {
        let corrupt = |e: serde_json::Error| SessionError::Corrupt(format!("manifest.json: {e}"));
        let header: Header = serde_json::from_slice(bytes).map_err(corrupt)?;
        if header.format != FORMAT {
            return Err(SessionError::NotASession(format!(
                "manifest.json names the format {:?}",
                header.format
            )));
        }
        if header.version > FORMAT_VERSION {
            return Err(SessionError::FutureVersion {
                found: header.version,
                supported: FORMAT_VERSION,
            });
        }
        let manifest: Self = serde_json::from_slice(bytes).map_err(corrupt)?;
        if manifest.camera != Camera::of(&manifest.config) {
            return Err(SessionError::Corrupt(
                "manifest.json: the camera differs from the configuration's".into(),
            ));
        }
        Ok(manifest)
    }

    /// The pipeline's scalars.
    #[must_use]
    pub fn scalars(&self) -> PipelineScalars {
        let [tracked, lost, recovered, held, lost_streak] = self.counts;
        PipelineScalars {
            frames: self.frames,
            counts: VerdictCounts {
                tracked,
                lost,
                recovered,
                held,
                restarted: self.restarted,
                lost_streak,
            },
            last_good: self.last_good.as_ref().map(pose_from_rows),
            placed_frame: self.placed_frame,
            measured_frame: self.measured_frame,
            velocity: self.velocity.as_ref().map(pose_from_rows),
            anchored: self.anchored,
            loop_counters: (
                self.loop_closures,
                self.global_loop_closures,
                self.last_global_closure,
            ),
            depth_checked: self.depth_checked,
            configured_noise: (self.configured_noise[0], self.configured_noise[1]),
            segment: Segment {
                start: self.segment[0],
                fused_before: self.segment[1],
            },
        }
    }

    /// The map's cleanup bookkeeping.
    #[must_use]
    pub fn schedule(&self) -> MapSchedule {
        MapSchedule {
            last_cleanup: self.last_cleanup,
            first_absorbed: self.first_absorbed,
            absorbed: self.absorbed,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::CameraPreset;

    #[test]
    fn every_preset_configuration_reads_back_the_same() {
        for preset in CameraPreset::ALL {
            let mut config = SlamConfig::from_preset(preset);
            // Values whose shortest decimal is long.
            config.intrinsics.fx = 1.0 / 3.0 + 500.0;
            config.loop_closure.deform.weight_constraint = 0.1 + 0.2;
            let text = serde_json::to_string(&config).unwrap();
            let back: SlamConfig = serde_json::from_str(&text).unwrap();
            assert_eq!(back, config, "{preset:?}");
            let bits =
                |c: &SlamConfig| (c.intrinsics.fx.to_bits(), c.tracker.noise.base_m.to_bits());
            assert_eq!(bits(&back), bits(&config));
        }
    }

    #[test]
    fn a_camera_difference_names_the_value() {
        let config = SlamConfig::from_preset(CameraPreset::TumFr1);
        let mut other = config.clone();
        other.depth.scale = 1000.0;
        let d = Camera::of(&config).difference(&Camera::of(&other)).unwrap();
        assert_eq!(d, "depth scale 5000 in the session, 1000 in use");
        assert_eq!(Camera::of(&config).difference(&Camera::of(&config)), None);
    }
}
