//! Ray casting in f32: boxes prepared for one ray origin, nearest hit (slab
//! method) and shading of the hit.

use glam::{DMat3, DVec3, Vec3};

use super::scene::Scene;
use super::texture::texture;

/// Rays closer than this (metres) to their origin do not count as hits.
const MIN_HIT_T: f32 = 1e-4;

/// A box ready for ray casting in f32, in its own frame.
#[derive(Debug, Clone, Copy)]
pub(super) struct PreparedBox {
    /// Lower corner minus the ray origin, box frame (the box is `-half..half`).
    lo_rel: Vec3,
    /// Upper corner minus the ray origin, box frame.
    hi_rel: Vec3,
    /// Ray origin in the box frame.
    origin_local: Vec3,
    /// Rows of box_from_world (identity for axis-aligned boxes).
    box_from_world: glam::Mat3,
    /// world_from_box.
    world_from_box: glam::Mat3,
    axis_aligned: bool,
    inside: bool,
    material: u32,
    /// Centre used to express texture coordinates: world origin for
    /// axis-aligned boxes (so textures are plain world functions), the box
    /// centre for rotated ones.
    texture_offset: Vec3,
}

impl PreparedBox {
    pub(super) fn normal_world(&self, axis: usize, dir_component: f32) -> Vec3 {
        let mut n = Vec3::ZERO;
        n[axis] = if dir_component > 0.0 { -1.0 } else { 1.0 };
        self.world_from_box * n
    }
}

pub(super) struct Prepared {
    pub(super) boxes: Vec<PreparedBox>,
}

#[derive(Debug, Clone, Copy)]
pub(super) struct Hit {
    pub(super) t: f32,
    pub(super) box_index: usize,
    pub(super) axis: usize,
    pub(super) dir_local: Vec3,
}

#[inline(always)]
fn safe_recip(d: Vec3) -> Vec3 {
    let fix = |x: f32| {
        if x.abs() < 1e-20 {
            1e20f32.copysign(x)
        } else {
            1.0 / x
        }
    };
    Vec3::new(fix(d.x), fix(d.y), fix(d.z))
}

impl Prepared {
    pub(super) fn new(scene: &Scene, origin: DVec3) -> Self {
        let mut boxes: Vec<PreparedBox> = scene
            .boxes
            .iter()
            .map(|b| {
                let world_from_box = DMat3::from_quat(b.rotation);
                let box_from_world = world_from_box.transpose();
                let origin_local = box_from_world * (origin - b.centre);
                PreparedBox {
                    lo_rel: (-b.half_size - origin_local).as_vec3(),
                    hi_rel: (b.half_size - origin_local).as_vec3(),
                    origin_local: origin_local.as_vec3(),
                    box_from_world: box_from_world.as_mat3(),
                    world_from_box: world_from_box.as_mat3(),
                    axis_aligned: b.is_axis_aligned(),
                    inside: b.seen_from_inside,
                    material: b.material,
                    texture_offset: if b.is_axis_aligned() {
                        b.centre.as_vec3()
                    } else {
                        Vec3::ZERO
                    },
                }
            })
            .collect();
        // Axis-aligned boxes first: cheaper, and most hits.
        boxes.sort_by_key(|b| !b.axis_aligned);
        Self { boxes }
    }

    /// Nearest hit along `dir` (world), `t` in units of `dir`.
    #[inline]
    pub(super) fn cast(&self, dir: Vec3) -> Option<Hit> {
        let inv_world = safe_recip(dir);
        let mut best: Option<Hit> = None;
        let mut best_t = f32::INFINITY;
        for (i, b) in self.boxes.iter().enumerate() {
            let (dir_local, inv) = if b.axis_aligned {
                (dir, inv_world)
            } else {
                let d = b.box_from_world * dir;
                (d, safe_recip(d))
            };
            let t0 = b.lo_rel * inv;
            let t1 = b.hi_rel * inv;
            let near = t0.min(t1);
            let far = t0.max(t1);
            let (t, axis) = if b.inside {
                let exit = far.min_element();
                if exit < near.max_element() {
                    continue;
                }
                (exit, argmin(far))
            } else {
                let enter = near.max_element();
                if enter > far.min_element() {
                    continue;
                }
                (enter, argmax(near))
            };
            if t > MIN_HIT_T && t < best_t {
                best_t = t;
                best = Some(Hit {
                    t,
                    box_index: i,
                    axis,
                    dir_local,
                });
            }
        }
        best
    }

    /// Colour (0..255 floats) of the surface at a hit.
    #[inline]
    pub(super) fn shade(&self, hit: &Hit) -> [f32; 3] {
        let b = &self.boxes[hit.box_index];
        let local = b.origin_local + hit.t * hit.dir_local + b.texture_offset;
        let positive_side = (hit.dir_local[hit.axis] > 0.0) == b.inside;
        let face = 2 * hit.axis as u32 + u32::from(positive_side);
        let a = local[(hit.axis + 1) % 3];
        let c = local[(hit.axis + 2) % 3];
        let normal = b.normal_world(hit.axis, hit.dir_local[hit.axis]);
        // Light from above (world -y is up), plus a little from +x +z.
        let light = Vec3::new(0.3, -0.85, 0.4).normalize();
        let shading = 0.8 + 0.2 * normal.dot(light);
        let rgb = texture(b.material, face, a, c);
        [rgb[0] * shading, rgb[1] * shading, rgb[2] * shading]
    }
}

#[inline(always)]
fn argmax(v: Vec3) -> usize {
    if v.x >= v.y && v.x >= v.z {
        0
    } else if v.y >= v.z {
        1
    } else {
        2
    }
}

#[inline(always)]
fn argmin(v: Vec3) -> usize {
    if v.x <= v.y && v.x <= v.z {
        0
    } else if v.y <= v.z {
        1
    } else {
        2
    }
}

#[cfg(test)]
mod tests {
    use crate::camera::Intrinsics;
    use crate::synthetic::test_support::small;
    use crate::synthetic::{render, trajectory, NoiseModel, Scene};

    #[test]
    fn back_projected_depth_lies_on_surfaces() {
        let scene = Scene::room();
        let ks = [
            small(),
            Intrinsics::new(120.3, -120.0, 79.5, 59.5, 160, 120),
        ];
        for (i, pose) in trajectory(300).iter().enumerate().step_by(37) {
            for k in &ks {
                let f = render(&scene, k, pose, &NoiseModel::none(), 7);
                let mut checked = 0;
                for v in (0..k.height).step_by(3) {
                    for u in (0..k.width).step_by(3) {
                        let z = f.depth_m[v * k.width + u];
                        assert!(z > 0.0, "closed room: every ray hits");
                        let p_cam = k.back_project(u as f32, v as f32, z).as_dvec3();
                        let p = pose.transform_point3(p_cam);
                        let d = scene.distance_to_surface(p);
                        assert!(d < 1e-3, "frame {i} pixel ({u},{v}) is {d} m off");
                        checked += 1;
                    }
                }
                assert!(checked > 2000);
            }
        }
    }
}
