//! Checks of a tracking result that do not share the dense tracker's
//! failure modes: the sparse feature estimate (descriptor matches do not
//! depend on where a search starts) and free-space violations (a point
//! measured where the model saw empty space says the pose is wrong,
//! whatever the residual of the surfaces that did line up).

use crate::camera::{pixel_of, Intrinsics};
use crate::features::FeatureConfig;
use crate::fusion::Prediction;
use crate::se3;
use glam::{Affine3A, DAffine3, Vec3};
use rayon::prelude::*;

/// When the sparse estimate runs, and how results are judged.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct VerifyConfig {
    /// Features, matching and RANSAC.
    pub features: FeatureConfig,
    /// Ask the sparse estimate when the dense result moved the camera more
    /// than this since the last fused frame (or since the start guess),
    /// metres. Frame-to-frame motion on the real sequences at their full
    /// rate is at most 2.3 cm / 2.1 degrees: there the sparse estimate
    /// never runs (and costs nothing).
    pub sparse_above_m: f64,
    /// As `sparse_above_m`, degrees.
    pub sparse_above_deg: f64,
    /// Run the sparse estimate on every frame (for measurements).
    pub sparse_always: bool,
    /// Dense and sparse estimates agree when they differ by less than this
    /// translation, metres. Measured against ground truth: the sparse
    /// estimate is within 1.0 cm of the truth on ICL-NUIM kt0 at strides
    /// 10 and 15 and 0.7 cm on the synthetic room, where a dense result
    /// that slid 3.1 cm along a wall must be refused; on TUM fr3/teddy it
    /// is up to 4.9 cm off while the dense result is right, which the
    /// second dense run from the sparse start settles (see the pipeline).
    pub agree_m: f64,
    /// ... and this rotation, degrees.
    pub agree_deg: f64,
    /// The dense tracker started at the sparse estimate may end this far
    /// from it, metres: it converges to the dense answer, and the sparse
    /// estimate is up to 4.9 cm from the truth on TUM fr3/teddy (stride 8,
    /// frame 18: dense from the constant-velocity guess went 89 cm wrong,
    /// the sparse estimate was 3.1 cm off, dense from there 0.5 cm).
    /// A slide along a plane goes further (30 cm on the synthetic room).
    pub landed_m: f64,
    /// ... and this rotation, degrees.
    pub landed_deg: f64,
    /// A frame point counts as a free-space violation when it lies this far
    /// in front of the model surface seen along its ray, metres (plus
    /// `free_space_margin_rel` times the model depth: depth noise grows
    /// with depth).
    pub free_space_margin_m: f32,
    /// Depth-proportional part of the margin.
    pub free_space_margin_rel: f32,
    /// A result is rejected when more than this fraction of the frame
    /// points that land on the model violate free space. Measured with the
    /// coarsest pyramid level's points (as the pipeline does): right poses
    /// give at most 0.026 on ICL-NUIM kt0 and 0.011 on TUM fr3/teddy
    /// (strides 1-15 / 1-8); the dense results that were 9-33 cm wrong on
    /// ICL-NUIM at strides 10 and 15 (constant velocity off) gave 0.20-0.42.
    pub max_free_space_fraction: f64,
    /// When the dense tracker started at the sparse estimate cannot pin
    /// the pose (conditioning below the re-acquisition bound), the sparse
    /// estimate itself is accepted if it has at least this many inliers ...
    pub sparse_only_min_inliers: usize,
    /// ... and an inlier RMS of at most this, metres.
    pub sparse_only_max_rms_m: f64,
    /// Start the dense tracker from the last pose times the last
    /// frame-to-frame motion (constant velocity) instead of the last pose.
    /// On by measurement (ATE, off -> on): TUM fr3/teddy strides 1/2/3/5/8
    /// 0.712/0.972/0.960/0.995/1.250 -> 0.673/0.906/0.905/0.868/0.857 cm
    /// (stride 8: one frame lost and one recovered, against none);
    /// ICL-NUIM kt0 unchanged at 0.011-0.012 cm (strides 1/5/10/15).
    pub constant_velocity: bool,
    /// While lost, carry the pose from frame to frame on the sparse
    /// estimate (each lost frame against the last one placed) and look for
    /// the model from there, instead of waiting at the last fused pose: a
    /// camera swung away from the map moves on meanwhile, and comes back
    /// where the last fused view no longer reaches (`examples/swings.rs`).
    /// Lost frames are still not fused. Off in sessions saved before it
    /// existed.
    #[serde(default)]
    pub dead_reckoning: bool,
    /// A lost frame is carried on only by an estimate with at least this
    /// many inlier matches (and an inlier RMS within `sparse_only_max_rms_m`).
    #[serde(default = "default_dead_reckoning_min_inliers")]
    pub dead_reckoning_min_inliers: usize,
}

fn default_dead_reckoning_min_inliers() -> usize {
    12
}

impl Default for VerifyConfig {
    fn default() -> Self {
        Self {
            features: FeatureConfig::default(),
            sparse_above_m: 0.04,
            sparse_above_deg: 4.0,
            sparse_always: false,
            agree_m: 0.02,
            agree_deg: 2.0,
            landed_m: 0.05,
            landed_deg: 3.0,
            free_space_margin_m: 0.05,
            free_space_margin_rel: 0.02,
            max_free_space_fraction: 0.1,
            sparse_only_min_inliers: 50,
            sparse_only_max_rms_m: 0.03,
            constant_velocity: true,
            dead_reckoning: true,
            dead_reckoning_min_inliers: default_dead_reckoning_min_inliers(),
        }
    }
}

impl VerifyConfig {
    /// The free-space margin at depth `z`, metres: how far a point may lie
    /// off a surface at that depth before it counts as another surface.
    #[inline]
    #[must_use]
    pub fn margin_at(&self, z: f32) -> f32 {
        self.free_space_margin_m + self.free_space_margin_rel * z
    }

    /// Where a point at depth `point_z` lies against the surface at depth
    /// `surface_z` on the same camera ray (metres), with the margin taken
    /// at the surface's depth: the one comparison of every free-space,
    /// see-through and same-surface check. Each passes the model's depth
    /// as the surface and the frame's as the point, whichever of the two
    /// was projected into the other's view.
    #[inline]
    #[must_use]
    pub fn side(&self, point_z: f32, surface_z: f32) -> Side {
        let margin = self.margin_at(surface_z);
        if point_z < surface_z - margin {
            Side::InFreeSpace
        } else if point_z > surface_z + margin {
            Side::Behind
        } else {
            Side::OnSurface
        }
    }

    /// Whether two `world_from_camera` poses agree within the bounds.
    #[must_use]
    pub fn agree(&self, a: &DAffine3, b: &DAffine3) -> bool {
        let (dt, dr) = se3::motion_magnitude(&(a.inverse() * *b));
        dt <= self.agree_m && dr.to_degrees() <= self.agree_deg
    }

    /// Whether the dense tracker started at the sparse estimate `sparse`
    /// stayed near it (within `landed_m` / `landed_deg`).
    #[must_use]
    pub fn landed_near(&self, dense: &DAffine3, sparse: &DAffine3) -> bool {
        let (dt, dr) = se3::motion_magnitude(&(dense.inverse() * *sparse));
        dt <= self.landed_m && dr.to_degrees() <= self.landed_deg
    }

    /// Whether two dense results are the same minimum (within 1 cm and 1
    /// degree: dense results from different starts that converged to one
    /// answer differ by millimetres).
    #[must_use]
    pub fn same_basin(&self, a: &DAffine3, b: &DAffine3) -> bool {
        let (dt, dr) = se3::motion_magnitude(&(a.inverse() * *b));
        dt <= 0.01 && dr.to_degrees() <= 1.0
    }
}

/// Where a point lies against a measured surface on its ray
/// ([`VerifyConfig::side`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    /// In front of the surface by more than the margin: where the surface's
    /// camera saw empty space.
    InFreeSpace,
    /// Within the margin of the surface: the same surface.
    OnSurface,
    /// Behind the surface by more than the margin: hidden by it.
    Behind,
}

/// A point seen from a camera (`camera_from_point`; the point in any frame,
/// metres) against the surface that camera's image holds on its ray:
/// `(point depth, pixel index, surface depth)`, or `None` when the point is
/// behind the camera, off the image, or `surface_z` has no surface at its
/// pixel (`None`). Every check that projects points onto another view's
/// depth goes through here.
#[inline]
#[must_use]
pub fn against_surface(
    k: &Intrinsics,
    camera_from_point: &Affine3A,
    p: Vec3,
    surface_z: impl Fn(usize) -> Option<f32>,
) -> Option<(f32, usize, f32)> {
    let (point_z, pixel) = pixel_of(k, camera_from_point.transform_point3(p))?;
    surface_z(pixel).map(|z| (point_z, pixel, z))
}

/// Fraction of the frame points (`vertices`, camera frame, metres, `ZERO`
/// where no depth, every `step`-th pixel) placed by `world_from_camera`
/// that lie in front of the model surface `prediction` shows along the same
/// ray of its own view by more than the margin; among the points that land
/// on a model pixel. Returns `(fraction, points that landed)`.
#[must_use]
pub fn free_space_violation(
    prediction: &Prediction,
    vertices: &[Vec3],
    step: usize,
    world_from_camera: &DAffine3,
    config: &VerifyConfig,
) -> (f64, usize) {
    let Some(k) = prediction.intrinsics else {
        return (0.0, 0);
    };
    if prediction.valid == 0 || prediction.vertices.len() != k.pixel_count() {
        return (0.0, 0);
    }
    let model_from_world = prediction.world_from_camera.inverse();
    let model_from_frame = (model_from_world * *world_from_camera).as_affine3a();
    let model_from_world = model_from_world.as_affine3a();
    let step = step.max(1);
    let (violations, landed) = vertices
        .par_chunks(4096)
        .map(|chunk| {
            let (mut violations, mut landed) = (0usize, 0usize);
            for p in chunk.iter().step_by(step) {
                if p.z <= 0.0 {
                    continue;
                }
                let model_z = |i: usize| {
                    let model = prediction.vertices[i];
                    (model != Vec3::ZERO).then(|| model_from_world.transform_point3(model).z)
                };
                let Some((q_z, _, z_model)) = against_surface(&k, &model_from_frame, *p, model_z)
                else {
                    continue;
                };
                landed += 1;
                if config.side(q_z, z_model) == Side::InFreeSpace {
                    violations += 1;
                }
            }
            (violations, landed)
        })
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    (violations as f64 / landed.max(1) as f64, landed)
}

/// What the independent checks said about one frame.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TrackingChecks {
    /// Free-space violation fraction of the dense tracker's first result
    /// (see [`free_space_violation`]).
    pub free_space_first: f64,
    /// The same for the pose finally reported (0 for lost frames).
    pub free_space_final: f64,
    /// The sparse estimate, when it ran and found one: the camera pose it
    /// implies (`world_from_camera`, metres) and its inlier matches.
    pub sparse: Option<(DAffine3, usize)>,
    /// RMS 3D distance of the sparse estimate's inliers, metres (0 without one).
    pub sparse_rms_m: f64,
    /// Whether the sparse estimate ran.
    pub sparse_ran: bool,
    /// Whether the reported pose came from the dense tracker started at the
    /// sparse estimate.
    pub from_sparse: bool,
    /// Whether the reported pose is the sparse estimate itself (the dense
    /// tracker could not pin the view).
    pub sparse_only: bool,
    /// The dense tracker's first result, `world_from_camera`.
    pub first_dense: Option<DAffine3>,
    /// When the frame was lost and then placed by relocalisation: the
    /// frame index of the keyframe it was placed by.
    pub relocalised_from: Option<u32>,
    /// Whether a lost frame's pose was carried on from the last placed
    /// frame by the sparse estimate ([`VerifyConfig::dead_reckoning`]).
    pub dead_reckoned: bool,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn side_takes_the_margin_at_the_surface() {
        let config = VerifyConfig::default();
        // At 2 m the margin is 5 cm + 2 % of 2 m = 9 cm.
        let margin = config.margin_at(2.0);
        assert!((margin - 0.09).abs() < 1e-6);
        assert_eq!(config.side(2.0 - 0.1, 2.0), Side::InFreeSpace);
        assert_eq!(config.side(2.0 - 0.08, 2.0), Side::OnSurface);
        assert_eq!(config.side(2.0 + 0.08, 2.0), Side::OnSurface);
        assert_eq!(config.side(2.0 + 0.1, 2.0), Side::Behind);
        // The margin is the surface's: 7 cm at 1 m, so a point 8.9 cm
        // behind a surface at 1 m is behind it, while 8.5 cm behind one at
        // 2 m is on it.
        assert_eq!(config.side(1.0 + 0.089, 1.0), Side::Behind);
        assert_eq!(config.side(2.085, 2.0), Side::OnSurface);
        assert_eq!(config.side(1.0 - 0.085, 1.0), Side::InFreeSpace);
    }

    #[test]
    fn against_surface_needs_a_surface_at_the_pixel() {
        let k = Intrinsics::new(100.0, 100.0, 50.0, 50.0, 100, 100);
        let identity = Affine3A::IDENTITY;
        let p = Vec3::new(0.0, 0.0, 2.0);
        let hit = against_surface(&k, &identity, p, |i| Some(i as f32));
        let (z, pixel, surface) = hit.expect("the centre pixel has a surface");
        assert_eq!(z, 2.0);
        assert_eq!(pixel, 50 * 100 + 50);
        assert_eq!(surface, pixel as f32);
        assert!(against_surface(&k, &identity, p, |_| None).is_none());
        assert!(against_surface(&k, &identity, -p, |_| Some(1.0)).is_none());
        assert!(against_surface(&k, &identity, Vec3::new(5.0, 0.0, 1.0), |_| Some(1.0)).is_none());
    }
}
