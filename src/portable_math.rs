//! Rotations built from sines, cosines and arctangents that give the same
//! bits on every target.
//!
//! `f64::sin`, `f32::exp` and the like call the platform's maths library:
//! glibc natively, compiler-builtins' port of musl in wasm32. Both are
//! within an ulp of the true value but not always the same ulp, and one
//! last bit of a filter weight or a pose grows through tracking into
//! millimetres (`docs/performance.md#determinism`). The pipeline therefore
//! calls the `libm` crate (the same code on every target) for every
//! transcendental function, and glam's constructors that call std's
//! (`from_rotation_z`, `from_angle`, `to_axis_angle`) are replaced here.
//! Square roots need nothing: IEEE 754 rounds them exactly everywhere.
//!
//! The bounds below are here for speed, not bits: `f32::max` must return
//! the other operand when one is NaN, which wasm's `f32.max` does not, so
//! in wasm it is a call to `fmaxf` per value (and a loop holding it is not
//! vectorised). In the per-pixel and per-surfel loops a compare and a
//! select does the same for operands that are never both NaN.

use glam::{DMat3, DQuat, DVec3, Vec2, Vec3};

/// `x.max(floor)`: `floor` where `x` is NaN, as std's. `floor` must not be
/// NaN. One compare and select on every target.
#[inline(always)]
#[must_use]
pub fn at_least(x: f32, floor: f32) -> f32 {
    if x > floor {
        x
    } else {
        floor
    }
}

/// `x.min(ceiling)`: `ceiling` where `x` is NaN, as std's. `ceiling` must
/// not be NaN. One compare and select on every target.
#[inline(always)]
#[must_use]
pub fn at_most(x: f32, ceiling: f32) -> f32 {
    if x < ceiling {
        x
    } else {
        ceiling
    }
}

/// Per-component minimum of two points that hold no NaN (box growth).
#[inline(always)]
#[must_use]
pub fn min_vec3(a: Vec3, b: Vec3) -> Vec3 {
    Vec3::new(at_most(a.x, b.x), at_most(a.y, b.y), at_most(a.z, b.z))
}

/// Per-component maximum of two points that hold no NaN (box growth).
#[inline(always)]
#[must_use]
pub fn max_vec3(a: Vec3, b: Vec3) -> Vec3 {
    Vec3::new(at_least(a.x, b.x), at_least(a.y, b.y), at_least(a.z, b.z))
}

/// Rotation by `angle` (radians) about the z axis (glam's
/// `DMat3::from_rotation_z`, computed with `libm`).
#[must_use]
pub fn rotation_z(angle: f64) -> DMat3 {
    let (s, c) = libm::sincos(angle);
    DMat3::from_cols(DVec3::new(c, s, 0.0), DVec3::new(-s, c, 0.0), DVec3::Z)
}

/// Unit quaternion of a rotation by `angle` (radians) about the unit
/// vector `axis` (glam's `DQuat::from_axis_angle`, computed with `libm`).
#[must_use]
pub fn quat_from_axis_angle(axis: DVec3, angle: f64) -> DQuat {
    let (s, c) = libm::sincos(angle * 0.5);
    let v = axis * s;
    DQuat::from_xyzw(v.x, v.y, v.z, c)
}

/// Axis and angle (radians, in [0, 2 pi]) of a unit quaternion (glam's
/// `DQuat::to_axis_angle`, computed with `libm`); the x axis and 0 for
/// (near-)identity.
#[must_use]
pub fn axis_angle(q: DQuat) -> (DVec3, f64) {
    let v = DVec3::new(q.x, q.y, q.z);
    let length = v.length();
    if length >= 1.0e-8 {
        (v / length, 2.0 * libm::atan2(length, q.w))
    } else {
        (DVec3::X, 0.0)
    }
}

/// The unit vector at `angle` (radians) from the x axis (glam's
/// `Vec2::from_angle`, computed with `libm`).
#[must_use]
pub fn unit_vec2(angle: f32) -> Vec2 {
    let (s, c) = libm::sincosf(angle);
    Vec2::new(c, s)
}

#[cfg(test)]
#[allow(clippy::disallowed_methods)] // std's maths in checks only, not on a result's path
mod tests {
    use super::*;

    #[test]
    fn bounds_give_std_s_bits_for_every_operand_but_signed_zeros() {
        let values = [
            f32::NAN,
            f32::NEG_INFINITY,
            -3.5,
            -1e-30,
            0.0,
            1e-6,
            0.25,
            1.0,
            7.0,
            f32::MAX,
            f32::INFINITY,
        ];
        for &x in &values {
            for &bound in values.iter().filter(|b| !b.is_nan()) {
                assert_eq!(
                    at_least(x, bound).to_bits(),
                    x.max(bound).to_bits(),
                    "{x} {bound}"
                );
                assert_eq!(
                    at_most(x, bound).to_bits(),
                    x.min(bound).to_bits(),
                    "{x} {bound}"
                );
            }
        }
        let (a, b) = (Vec3::new(1.0, -2.0, 3.0), Vec3::new(0.5, 4.0, 3.0));
        assert_eq!(min_vec3(a, b), a.min(b));
        assert_eq!(max_vec3(a, b), a.max(b));
    }

    #[test]
    fn agree_with_glam_within_an_ulp_or_two() {
        for i in -40..=40 {
            let a = f64::from(i) * 0.173;
            let m = rotation_z(a) - DMat3::from_rotation_z(a);
            assert!(m.to_cols_array().iter().all(|d| d.abs() < 1e-15), "{a}");
            let axis = DVec3::new(0.3, -0.5, 0.8).normalize();
            let q = quat_from_axis_angle(axis, a);
            assert!(q.abs_diff_eq(DQuat::from_axis_angle(axis, a), 1e-15), "{a}");
            let (ax, an) = axis_angle(q);
            let (gx, gn) = q.to_axis_angle();
            assert!(ax.abs_diff_eq(gx, 1e-12) && (an - gn).abs() < 1e-12, "{a}");
            let v = unit_vec2(a as f32);
            assert!(v.abs_diff_eq(Vec2::from_angle(a as f32), 1e-6), "{a}");
        }
        assert_eq!(axis_angle(DQuat::IDENTITY), (DVec3::X, 0.0));
    }
}
