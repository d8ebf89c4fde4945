//! Loop closure: SLAM rather than odometry (ElasticFusion, Whelan et al. 2015/2016).
//!
//! - `local` (model to model): the active part of the map (surfels updated in
//!   the last window of frames) registered against the inactive part seen
//!   from the same pose.
//! - `ferns` (global): a keyframe database of compact whole-image codes
//!   (randomised ferns, Glocker et al. 2015) to find a revisited place when
//!   drift is too large for the local check, and to relocalise a lost camera.
//! - `deformation`: an embedded deformation graph that bends every surfel and
//!   every past pose to satisfy the constraints an accepted closure gives.
//!
//! Poses are `world_from_camera` (metres); times are frame indices.

pub mod deformation;
pub mod ferns;
pub mod global;
pub mod relocalise;
