//! surfel-slam: dense RGB-D SLAM with point-based (surfel) fusion.
//!
//! The whole algorithm lives in this crate; the CLI (`src/bin`), the wasm
//! bindings (`wasm`) and the browser page are thin shells over [`Pipeline`].
//!
//! Conventions: camera frame +x right, +y down, +z forward; metres; poses
//! named for what they map (`world_from_camera`); depth 0 = no measurement.

// Same bits natively and in wasm: std's exp, sin, atan2... are glibc's
// natively and compiler-builtins' in wasm32 (clippy.toml lists them; use the
// libm crate, docs/performance.md#determinism).
#![deny(clippy::disallowed_methods)]

pub mod camera;
pub mod clock;
pub mod dataset;
pub mod eval;
pub mod features;
pub mod flow;
pub mod frame;
pub mod fusion;
pub mod imu;
pub mod loop_closure;
pub mod mesh;
pub mod noise;
pub mod ordered_sum;
pub mod pipeline;
mod pool;
pub mod portable_math;
mod prefetch;
pub mod preprocess;
pub mod random;
pub mod se3;
pub mod session;
pub mod simulated_noise;
pub mod synthetic;
pub mod track;
#[cfg(target_arch = "wasm32")]
pub mod wasm;

pub use camera::{CameraPreset, Intrinsics};
pub use frame::{DepthSettings, FrameError, RgbdFrame};
pub use fusion::SurfelMap;
pub use noise::SensorNoise;
pub use pipeline::{FrameReport, Pipeline, PipelineError, SlamConfig, StageTimings, Verdict};
