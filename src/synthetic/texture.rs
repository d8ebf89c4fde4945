//! Procedural, view-independent surface colour: per-face base colours,
//! checkerboards and sinusoids, with libm-free helpers.

fn hash32(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7FEB_352D);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846C_A68B);
    x ^= x >> 16;
    x
}

/// +1 / -1 checkerboard of square size `cell` (metres) in the face plane.
#[inline(always)]
fn checker(a: f32, b: f32, cell: f32) -> f32 {
    let i = floor_i32(a / cell).wrapping_add(floor_i32(b / cell));
    if i & 1 == 0 {
        1.0
    } else {
        -1.0
    }
}

/// floor(x) as an integer without a libm call (saturates far outside the room; NaN gives 0).
#[inline(always)]
fn floor_i32(x: f32) -> i32 {
    let i = x as i32;
    if (i as f32) > x {
        i - 1
    } else {
        i
    }
}

/// sin(2 pi x), x in turns, to about 1e-3: a polynomial, so it is cheap and
/// gives bit-identical results on every platform (no libm).
#[inline(always)]
pub(super) fn sin_turns(x: f32) -> f32 {
    let t = x - floor_i32(x + 0.5) as f32; // -0.5..0.5 turns
    let y = 8.0 * t - 16.0 * t * t.abs();
    0.225 * (y * y.abs() - y) + y
}

/// Material of an office ceiling ([`super::Scene::with_office_ceiling`]):
/// plain paint with one light panel and a few vents, texture only where
/// they are (a real ceiling, not the room's patterned faces).
pub const CEILING_MATERIAL: u32 = 0xCE11;

/// The office ceiling at world `(z, x)` (metres, the face's in-plane
/// coordinates): off-white paint (205), a 1.0 x 0.5 m light panel (250)
/// in a 2 cm dark frame centred at x = 0.3, z = 0.4, and three 0.25 m
/// square vents of slats every 2.5 cm.
#[inline]
fn ceiling(z: f32, x: f32) -> f32 {
    let (px, pz) = ((x - 0.3).abs(), (z - 0.4).abs());
    if px < 0.5 && pz < 0.25 {
        return if px > 0.48 || pz > 0.23 { 110.0 } else { 250.0 };
    }
    for (vx, vz) in [(-0.5, 0.1), (1.1, 0.8), (0.8, -0.1)] {
        let (dx, dz) = ((x - vx).abs(), (z - vz).abs());
        if dx < 0.125 && dz < 0.125 {
            return if dx > 0.11 || dz > 0.11 || sin_turns(z / 0.025) > 0.0 {
                150.0
            } else {
                70.0
            };
        }
    }
    205.0
}

/// Procedural texture of face `face` (0..6) of material `material` at in-plane
/// coordinates (a, b), metres; returns linear 0..255 RGB before shading.
#[inline]
pub(super) fn texture(material: u32, face: u32, a: f32, b: f32) -> [f32; 3] {
    if material == CEILING_MATERIAL {
        let grey = ceiling(a, b);
        return [grey, grey * 0.98, grey * 0.95];
    }
    let hsh = hash32(material.wrapping_mul(16) + face + 1);
    // Base colour: each channel 90..200 from the hash.
    let base = [
        90.0 + (hsh & 0xFF) as f32 * (110.0 / 255.0),
        90.0 + ((hsh >> 8) & 0xFF) as f32 * (110.0 / 255.0),
        90.0 + ((hsh >> 16) & 0xFF) as f32 * (110.0 / 255.0),
    ];
    // Phases in turns (cycles).
    let phase = ((hsh >> 24) & 0xFF) as f32 * (1.0 / 256.0);
    let coarse = checker(a, b, 0.5);
    let fine = checker(a + 0.037, b - 0.021, 0.1);
    let wave1 = sin_turns(a * (1.0 / 0.23) + phase) * sin_turns(b * (1.0 / 0.31) - phase);
    let wave2 = sin_turns((a + 0.6 * b) * (1.0 / 0.47) + 2.0 * phase);
    let wave3 = sin_turns((0.8 * a - b) * (1.0 / 0.13) + phase);
    let gain = 1.0 + 0.22 * coarse + 0.08 * fine;
    let mut out = [0.0; 3];
    for (ch, (o, base)) in out.iter_mut().zip(base).enumerate() {
        let w = [1.0, 0.6, 0.8][ch];
        let v = base * gain + 30.0 * w * wave1 + 18.0 * wave2 + 12.0 * (1.6 - w) * wave3;
        *o = v.clamp(0.0, 255.0);
    }
    out
}

#[cfg(test)]
#[allow(clippy::disallowed_methods)] // std's maths in checks only, not on a result's path
mod tests {
    use crate::synthetic::{default_intrinsics, render, trajectory_pose, NoiseModel, Scene};

    #[test]
    fn texture_has_gradients_everywhere() {
        let scene = Scene::room();
        let k = default_intrinsics();
        let f = render(&scene, &k, &trajectory_pose(0), &NoiseModel::none(), 0);
        let grey: Vec<f32> = f
            .rgb
            .chunks_exact(3)
            .map(|p| 0.299 * f32::from(p[0]) + 0.587 * f32::from(p[1]) + 0.114 * f32::from(p[2]))
            .collect();
        let w = k.width;
        let mut strong = 0;
        let mut total = 0;
        for v in 1..k.height - 1 {
            for u in 1..w - 1 {
                let gx = 0.5 * (grey[v * w + u + 1] - grey[v * w + u - 1]);
                let gy = 0.5 * (grey[(v + 1) * w + u] - grey[(v - 1) * w + u]);
                if gx.hypot(gy) > 1.0 {
                    strong += 1;
                }
                total += 1;
            }
        }
        let fraction = f64::from(strong) / f64::from(total);
        assert!(
            fraction > 0.8,
            "only {fraction} of pixels have gradient > 1"
        );
    }
}
