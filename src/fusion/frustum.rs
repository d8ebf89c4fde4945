//! The view frustum of a camera as six world-frame planes, for culling the
//! map's block boxes.

use crate::camera::Intrinsics;
use crate::fusion::SurfelMap;
use crate::se3::RigidF32;
use glam::Vec3;
use std::ops::Range;

/// Nearest depth considered by culling, metres (sensors see nothing closer).
const NEAR_M: f32 = 0.05;

/// Writes into `out` the surfel index ranges of the map blocks that may be
/// visible from `camera_from_world` up to depth `far_m` (metres), may hold
/// a surfel last updated at a frame in `seen`, and whose box (world frame)
/// `also` accepts.
pub fn visible_blocks(
    map: &SurfelMap,
    k: &Intrinsics,
    (camera_from_world, far_m): (&RigidF32, f32),
    seen: &Range<u32>,
    mut also: impl FnMut(Vec3, Vec3) -> bool,
    out: &mut Vec<Range<usize>>,
) {
    let frustum = Frustum::new(k, camera_from_world, NEAR_M, far_m);
    map.bounds().select(
        map.len(),
        seen,
        |lo, hi| frustum.may_contain_box(lo, hi) && also(lo, hi),
        out,
    );
}

/// Half-spaces `normal . x + offset >= 0` (world frame, metres) bounding what
/// a camera can see between `near` and `far` depth.
#[derive(Debug, Clone, Copy)]
pub struct Frustum {
    planes: [(Vec3, f32); 6],
}

impl Frustum {
    /// The frustum of the image `k` (plus a one-pixel margin) seen from
    /// `camera_from_world`, between depths `near_m` and `far_m`.
    #[must_use]
    pub fn new(k: &Intrinsics, camera_from_world: &RigidF32, near_m: f32, far_m: f32) -> Self {
        let (w, h) = (k.width as f32, k.height as f32);
        let corners = [
            k.back_project(-1.5, -1.5, 1.0),
            k.back_project(w + 0.5, -1.5, 1.0),
            k.back_project(w + 0.5, h + 0.5, 1.0),
            k.back_project(-1.5, h + 0.5, 1.0),
        ];
        let mut camera_planes = [
            (Vec3::Z, -near_m),
            (-Vec3::Z, far_m),
            (Vec3::Z, 0.0),
            (Vec3::Z, 0.0),
            (Vec3::Z, 0.0),
            (Vec3::Z, 0.0),
        ];
        for s in 0..4 {
            // A side plane through the camera centre and two adjacent corner
            // rays, turned to face the optical axis (handles negative focal lengths).
            let n = corners[s].cross(corners[(s + 1) % 4]);
            camera_planes[2 + s] = (if n.z < 0.0 { -n } else { n }, 0.0);
        }
        // n_c . (R x + t) + d = (R^T n_c) . x + (n_c . t + d)
        let rt = camera_from_world.rotation.transpose();
        let planes = camera_planes.map(|(n, d)| (rt * n, n.dot(camera_from_world.translation) + d));
        Self { planes }
    }

    /// False only when the box `[min, max]` lies entirely outside one plane.
    #[must_use]
    pub fn may_contain_box(&self, min: Vec3, max: Vec3) -> bool {
        self.planes.iter().all(|&(n, d)| {
            // The box corner farthest along the plane normal.
            let far = Vec3::select(n.cmpge(Vec3::ZERO), max, min);
            n.dot(far) + d >= 0.0
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DAffine3, DVec3};

    #[test]
    fn culls_boxes_behind_beside_and_beyond() {
        for fy in [525.0, -525.0] {
            let k = Intrinsics::new(525.0, fy, 319.5, 239.5, 640, 480);
            let world_from_camera = DAffine3::from_translation(DVec3::new(1.0, 0.0, 0.0));
            let t = RigidF32::from_affine(&world_from_camera.inverse());
            let f = Frustum::new(&k, &t, 0.1, 5.0);
            let cube = |c: Vec3| (c - Vec3::splat(0.05), c + Vec3::splat(0.05));
            let sees = |c: Vec3| {
                let (lo, hi) = cube(c);
                f.may_contain_box(lo, hi)
            };
            assert!(sees(Vec3::new(1.0, 0.0, 2.0)));
            assert!(sees(Vec3::new(1.0, 0.9, 2.0)), "inside near the image edge");
            assert!(!sees(Vec3::new(1.0, 0.0, -2.0)), "behind");
            assert!(!sees(Vec3::new(4.0, 0.0, 2.0)), "beside");
            assert!(!sees(Vec3::new(1.0, 0.0, 6.0)), "beyond far");
            // A box straddling the side plane is kept.
            assert!(f.may_contain_box(Vec3::new(0.0, 0.0, 1.9), Vec3::new(5.0, 0.1, 2.0)));
        }
    }
}
