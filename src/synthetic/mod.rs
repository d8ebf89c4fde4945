//! Deterministic ray-cast renderer of a synthetic indoor scene, with a known
//! camera trajectory: exact answers for unit tests, wasm tests and benchmarks.
//!
//! # Conventions
//!
//! - World axes: **world -y is up** (gravity along +y), matching the camera's
//!   +y-down convention, so a camera with identity rotation is upright. The
//!   floor is the plane `y = 0`, the ceiling `y = -3`.
//! - The default room ([`Scene::room`]) spans `x, z in [-3, 3]`, `y in [-3, 0]`
//!   (6 m x 3 m high x 6 m), seen from inside, with six boxes on the floor: four
//!   axis-aligned, one turned 35 degrees about the vertical and one tilted slab
//!   (a ramp), so that point-to-plane ICP is constrained in all six degrees of
//!   freedom.
//! - Every surface carries a procedural texture that depends only on the world
//!   point and on which face it lies (never on the view): a per-face base
//!   colour, checkerboards at 0.5 m and 0.1 m, and sinusoids of 0.1 to 0.5 m
//!   period, so intensity has strong gradients almost everywhere and fused
//!   colour is consistent between views. A fixed light from above shades faces
//!   by their normal (view-independent too).
//! - Depth is z-depth (along the optical axis) in metres; raw depth is 16-bit
//!   with [`DEPTH_UNITS_PER_METRE`] units per metre, 0 = hole, like TUM RGB-D
//!   and ICL-NUIM.
//!
//! Rendering is per pixel, through the pixel centre, nearest hit over all
//! boxes (slab method), parallel over rows with rayon. Noise is drawn from a
//! [`crate::random::SplitMix`] stream seeded per row from `seed`, so a frame depends only on
//! its arguments (not on the thread count).

mod hand;
mod imu;
mod loop_path;
mod map_error;
mod noise;
mod raycast;
mod render;
mod scene;
mod swing;
mod texture;
mod trajectory;

pub use hand::hold_hand_in_view;
pub use imu::{ImuSimulation, STANDARD_GRAVITY_MPS2};
pub use loop_path::{loop_pose, loop_pose_at};
pub use map_error::{map_error, MapError};
pub use noise::{NoiseModel, StructuredLight};
pub use render::{
    depth_settings, render, render_into, RenderedFrame, SyntheticError, DEPTH_UNITS_PER_METRE,
};
pub use scene::{Scene, SceneBox, ROOM_MAX, ROOM_MIN};
pub use swing::{render_blurred, turn_between_deg, SwingPath};
pub use texture::CEILING_MATERIAL;
pub use trajectory::{
    default_intrinsics, look_at, trajectory, trajectory_pose, trajectory_pose_at,
};

/// Small intrinsics and depth settings shared by the unit tests of the submodules.
#[cfg(test)]
mod test_support {
    use crate::camera::Intrinsics;
    use crate::frame::DepthSettings;

    pub(super) fn small() -> Intrinsics {
        Intrinsics::new(131.25, 131.25, 79.5, 59.5, 160, 120)
    }

    pub(super) fn settings() -> DepthSettings {
        super::depth_settings()
    }
}
