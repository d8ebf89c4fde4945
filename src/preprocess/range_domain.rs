//! The bilateral filter's range domain: depth remapped beyond a knee so
//! that one range sigma spans as many noise deviations at every depth
//! ([`super::PreprocessConfig::range_noise_factor`]). Depths in metres.

use super::PreprocessConfig;
use crate::noise::SensorNoise;

/// Nearest knee [`range_knee_m`] gives, metres: a model whose constant
/// part alone exceeds the range sigma grows it from here.
const MIN_RANGE_KNEE_M: f32 = 0.1;

/// Depth (m) beyond which the bilateral range sigma grows with `noise`
/// ([`PreprocessConfig::range_noise_factor`]): where that many axial
/// deviations reach `sigma_depth_m`. `None` when it stays constant (the
/// factor is 0, or the model's deviation does not grow with depth).
#[must_use]
pub fn range_knee_m(config: &PreprocessConfig, noise: &SensorNoise) -> Option<f32> {
    if config.range_noise_factor.is_nan() || config.range_noise_factor <= 0.0 {
        return None;
    }
    let knee = noise.depth_where_axial_reaches(config.sigma_depth_m / config.range_noise_factor)?;
    Some(knee.max(MIN_RANGE_KNEE_M))
}

/// Depth `z` (m) in the bilateral filter's range domain: unchanged up to
/// `knee`, beyond it `2 knee - knee^2 / z`, so a depth step counts
/// `(knee / z)^2` of itself there, as disparity noise grows with `z^2`.
/// Affine in inverse depth beyond the knee, which is itself affine in
/// pixel coordinates across a plane: averaging there does not bend planes.
/// 0 (no depth) stays 0.
#[inline]
pub(super) fn to_range_domain(z: f32, knee: f32) -> f32 {
    // Both sides computed and one selected, so that the loop vectorises.
    let far = 2.0 * knee - knee * knee / z.max(knee);
    if z <= knee {
        z
    } else {
        far
    }
}

/// The inverse of [`to_range_domain`] (values of the domain stay below
/// `2 knee`; the guard keeps a rounding there finite).
#[inline]
pub(super) fn from_range_domain(g: f32, knee: f32) -> f32 {
    let far = knee * knee / (2.0 * knee - g).max(knee * 1e-4);
    if g <= knee {
        g
    } else {
        far
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_range_domain_is_monotonic_and_inverts() {
        let knee = 2.2;
        let mut previous = -1.0;
        for i in 0..=2000 {
            let z = i as f32 * 0.01;
            let g = to_range_domain(z, knee);
            assert!(g > previous && g < 2.0 * knee, "{z} -> {g}");
            let back = from_range_domain(g, knee);
            assert!(
                (back - z).abs() <= 2e-6 * z.max(1.0) * z.max(1.0),
                "{z} -> {g} -> {back}"
            );
            previous = g;
        }
        assert_eq!(to_range_domain(0.0, knee), 0.0);
        assert!(from_range_domain(2.0 * knee, knee).is_finite());
    }
}
