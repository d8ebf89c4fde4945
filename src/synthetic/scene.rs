//! Scene geometry: boxes (solid or seen from inside), the default room, and
//! distance / free-space queries and single-ray casting.

use glam::{DQuat, DVec3};

use super::raycast::Prepared;

/// Lower corner of the default room ([`Scene::room`]), metres. World -y is up.
pub const ROOM_MIN: DVec3 = DVec3::new(-3.0, -3.0, -3.0);
/// Upper corner of the default room ([`Scene::room`]), metres; `y = 0` is the floor.
pub const ROOM_MAX: DVec3 = DVec3::new(3.0, 0.0, 3.0);

/// One box of the scene: a solid block, or the room itself seen from inside.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SceneBox {
    /// Centre, world frame, metres.
    pub centre: DVec3,
    /// Half of the size along each of the box's own axes, metres.
    pub half_size: DVec3,
    /// Rotation world_from_box (identity for an axis-aligned box).
    pub rotation: DQuat,
    /// `true` for the enclosing room: rays start inside and hit where they leave.
    pub seen_from_inside: bool,
    /// Selects the texture (base colours and pattern phases) of the six faces.
    pub material: u32,
}

impl SceneBox {
    /// A solid axis-aligned box between two corners.
    #[must_use]
    pub fn solid(min: DVec3, max: DVec3, material: u32) -> Self {
        let (lo, hi) = (min.min(max), min.max(max));
        Self {
            centre: 0.5 * (lo + hi),
            half_size: 0.5 * (hi - lo),
            rotation: DQuat::IDENTITY,
            seen_from_inside: false,
            material,
        }
    }

    /// A solid box of the given half size, rotated by `rotation` (world_from_box) about its centre.
    #[must_use]
    pub fn rotated(centre: DVec3, half_size: DVec3, rotation: DQuat, material: u32) -> Self {
        Self {
            centre,
            half_size: half_size.abs(),
            rotation: rotation.normalize(),
            seen_from_inside: false,
            material,
        }
    }

    /// An axis-aligned room between two corners, seen from inside.
    #[must_use]
    pub fn room(min: DVec3, max: DVec3, material: u32) -> Self {
        Self {
            seen_from_inside: true,
            ..Self::solid(min, max, material)
        }
    }

    pub(super) fn is_axis_aligned(&self) -> bool {
        let q = self.rotation;
        (q.w.abs() - 1.0).abs() < 1e-12
    }

    /// Distance from `point` (world) to the nearest face of the box, metres
    /// (whether the point is inside or outside).
    #[must_use]
    pub fn distance_to_surface(&self, point: DVec3) -> f64 {
        let local = self.rotation.inverse() * (point - self.centre);
        let d = local.abs() - self.half_size;
        let outside = d.max(DVec3::ZERO).length();
        let inside = d.max_element().min(0.0);
        (outside + inside).abs()
    }

    /// Whether `point` (world) lies strictly inside the box volume.
    #[must_use]
    pub fn contains(&self, point: DVec3) -> bool {
        let local = self.rotation.inverse() * (point - self.centre);
        (local.abs() - self.half_size).max_element() < 0.0
    }
}

/// A synthetic scene: boxes, each face with a procedural texture.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// All boxes, the room included.
    pub boxes: Vec<SceneBox>,
}

impl Default for Scene {
    fn default() -> Self {
        Self::room()
    }
}

impl Scene {
    /// The default scene: a 6 x 3 x 6 m room ([`ROOM_MIN`]..[`ROOM_MAX`], world -y up,
    /// floor at y = 0) with six boxes on the floor near the walls, one of them
    /// turned 35 degrees about the vertical and one a slab tilted 25 degrees (a ramp).
    /// Every point within 1.25 m of the room's vertical centre line and 1.3..1.6 m
    /// above the floor is at least 0.95 m from every surface (that is where
    /// [`trajectory`](fn@super::trajectory) runs).
    #[must_use]
    pub fn room() -> Self {
        let boxes = vec![
            SceneBox::room(ROOM_MIN, ROOM_MAX, 0),
            // Table-height block.
            SceneBox::solid(DVec3::new(1.4, -0.75, 1.5), DVec3::new(2.5, 0.0, 2.4), 1),
            // Tall cabinet against the -x wall.
            SceneBox::solid(DVec3::new(-2.9, -1.9, 1.5), DVec3::new(-2.1, 0.0, 2.5), 2),
            // Small cube.
            SceneBox::solid(DVec3::new(0.3, -0.5, -2.3), DVec3::new(0.8, 0.0, -1.8), 3),
            // Low wide block.
            SceneBox::solid(DVec3::new(-2.4, -0.4, -2.2), DVec3::new(-1.2, 0.0, -1.4), 4),
            // Pillar turned 35 degrees about the vertical.
            SceneBox::rotated(
                DVec3::new(2.2, -0.6, -1.5),
                DVec3::new(0.3, 0.6, 0.35),
                crate::portable_math::quat_from_axis_angle(DVec3::Y, 35f64.to_radians()),
                5,
            ),
            // Ramp: a thin slab tilted 25 degrees about x, resting on the floor.
            SceneBox::rotated(
                DVec3::new(-0.3, -0.24, 2.3),
                DVec3::new(0.7, 0.03, 0.5),
                crate::portable_math::quat_from_axis_angle(DVec3::X, 25f64.to_radians()),
                6,
            ),
        ];
        Self { boxes }
    }

    /// The room ([`Self::room`]) under an office ceiling: a 10 cm slab just
    /// below the room's ceiling (its underside at `y = -2.9`) painted as
    /// [`super::CEILING_MATERIAL`], plain but for one light panel and three
    /// vents. Looking up, the view is one plane whose only texture is
    /// theirs.
    #[must_use]
    pub fn with_office_ceiling() -> Self {
        let mut scene = Self::room();
        scene.boxes.push(SceneBox::solid(
            DVec3::new(ROOM_MIN.x + 0.01, ROOM_MIN.y, ROOM_MIN.z + 0.01),
            DVec3::new(ROOM_MAX.x - 0.01, ROOM_MIN.y + 0.1, ROOM_MAX.z - 0.01),
            super::CEILING_MATERIAL,
        ));
        scene
    }

    /// Distance from `point` (world) to the nearest box face, metres
    /// (`f64::INFINITY` for an empty scene).
    #[must_use]
    pub fn distance_to_surface(&self, point: DVec3) -> f64 {
        self.boxes
            .iter()
            .map(|b| b.distance_to_surface(point))
            .fold(f64::INFINITY, f64::min)
    }

    /// Whether `point` is in free space: inside every room and outside every solid box.
    #[must_use]
    pub fn is_free(&self, point: DVec3) -> bool {
        self.boxes
            .iter()
            .all(|b| b.contains(point) == b.seen_from_inside)
    }

    /// Casts one ray (world frame); returns the ray parameter `t` of the nearest
    /// hit (the hit is `origin + t * direction`) and the surface normal there
    /// (unit, facing the ray), or `None` when nothing is hit.
    #[must_use]
    pub fn cast_ray(&self, origin: DVec3, direction: DVec3) -> Option<(f64, DVec3)> {
        let prepared = Prepared::new(self, origin);
        let hit = prepared.cast(direction.as_vec3())?;
        let b = &prepared.boxes[hit.box_index];
        let n = b.normal_world(hit.axis, hit.dir_local[hit.axis]);
        Some((f64::from(hit.t), n.as_dvec3()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Intrinsics;
    use crate::synthetic::test_support::small;
    use crate::synthetic::{default_intrinsics, look_at, render, trajectory, NoiseModel};

    #[test]
    fn depth_to_a_wall_is_exact() {
        let scene = Scene::room();
        // Looking along +z at the wall z = 3 from z = 0.5: depth 2.5 everywhere on it.
        let eye = DVec3::new(0.1, -1.5, 0.5);
        let pose = look_at(eye, eye + DVec3::Z);
        for k in [
            default_intrinsics(),
            small(),
            Intrinsics::new(481.2, -480.0, 319.5, 239.5, 640, 480),
        ] {
            let f = render(&scene, &k, &pose, &NoiseModel::none(), 1);
            let centre = (k.height / 2) * k.width + k.width / 2;
            assert!(
                (f.depth_m[centre] - 2.5).abs() < 1e-4,
                "{}",
                f.depth_m[centre]
            );
            assert_eq!(f.depth_raw[centre], 12500);
        }
        // Looking straight down at the floor from 1.2 m above it.
        let eye = DVec3::new(-0.4, -1.2, 0.3);
        let pose = look_at(eye, eye + DVec3::Y);
        let k = small();
        let f = render(&scene, &k, &pose, &NoiseModel::none(), 1);
        let centre = (k.height / 2) * k.width + k.width / 2;
        assert!(
            (f.depth_m[centre] - 1.2).abs() < 1e-4,
            "{}",
            f.depth_m[centre]
        );
        // And through the public single-ray API.
        let (t, n) = scene.cast_ray(eye, DVec3::Y).expect("floor is hit");
        assert!((t - 1.2).abs() < 1e-4 && (n - DVec3::NEG_Y).length() < 1e-6);
    }

    /// Smallest and largest eigenvalues of a symmetric 6x6 matrix (cyclic Jacobi).
    fn eigen_range(mut a: [[f64; 6]; 6]) -> (f64, f64) {
        for _ in 0..30 {
            for p in 0..6 {
                for q in p + 1..6 {
                    if a[p][q].abs() < 1e-300 {
                        continue;
                    }
                    let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
                    let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                    let c = 1.0 / (t * t + 1.0).sqrt();
                    let s = t * c;
                    for row in a.iter_mut() {
                        let (x, y) = (row[p], row[q]);
                        row[p] = c * x - s * y;
                        row[q] = s * x + c * y;
                    }
                    let (rp, rq) = (a[p], a[q]);
                    a[p] = std::array::from_fn(|k| c * rp[k] - s * rq[k]);
                    a[q] = std::array::from_fn(|k| s * rp[k] + c * rq[k]);
                }
            }
        }
        (0..6).fold((f64::INFINITY, 0.0f64), |(lo, hi), i| {
            (lo.min(a[i][i]), hi.max(a[i][i]))
        })
    }

    #[test]
    fn views_constrain_all_six_degrees_of_freedom() {
        // Point-to-plane ICP information matrix sum J J^T, J = [p x n, n] in
        // the camera frame: well conditioned along the whole trajectory.
        let mut known = [[0.0f64; 6]; 6];
        for (i, row) in known.iter_mut().enumerate() {
            row[i] = i as f64 + 1.0;
            row[(i + 1) % 6] = 0.1;
        }
        let sym: [[f64; 6]; 6] =
            std::array::from_fn(|i| std::array::from_fn(|j| known[i][j] + known[j][i]));
        let (lo, hi) = eigen_range(sym);
        assert!(lo > 1.5 && lo < 2.5 && hi > 11.5 && hi < 12.5, "{lo} {hi}");

        let scene = Scene::room();
        let k = small();
        for pose in trajectory(600).iter().step_by(30) {
            let f = render(&scene, &k, pose, &NoiseModel::none(), 0);
            let camera_from_world = pose.inverse();
            let mut info = [[0.0f64; 6]; 6];
            for v in (0..k.height).step_by(3) {
                for u in (0..k.width).step_by(3) {
                    let z = f.depth_m[v * k.width + u];
                    let p = k.back_project(u as f32, v as f32, z).as_dvec3();
                    let (_, n_world) = scene
                        .cast_ray(pose.translation, pose.transform_vector3(p))
                        .expect("closed room");
                    let n = camera_from_world.transform_vector3(n_world);
                    let r = p.cross(n);
                    let j = [r.x, r.y, r.z, n.x, n.y, n.z];
                    for (row, &ja) in info.iter_mut().zip(&j) {
                        for (x, &jb) in row.iter_mut().zip(&j) {
                            *x += ja * jb;
                        }
                    }
                }
            }
            let (lo, hi) = eigen_range(info);
            assert!(lo / hi > 2e-3, "ill-conditioned view: {lo} / {hi}");
        }
    }
}
