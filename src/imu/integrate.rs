//! The gyro integrated between two times: the device's rotation over the
//! interval, from rates linearly interpolated between samples (so the ends
//! of the interval need no sample of their own).
//!
//! Each piece between two consecutive breakpoints (the interval's ends and
//! the samples inside it) turns by the exact exponential of its mean rate
//! times its length: for a rate linear in time that mean is the rate at
//! the piece's midpoint (the midpoint rule), and what it leaves out is
//! the commutator of the rate with its change over one sample interval,
//! below 1e-7 rad a piece at hand-held rates sampled at 100 Hz.

use glam::{DQuat, DVec3};

use super::{ImuError, ImuSample};
use crate::portable_math::quat_from_axis_angle;

/// The longest gap between two samples whose rate is interpolated,
/// seconds: ten samples of a 100 Hz IMU missing, beyond which a hand's
/// rate is no longer a straight line between them.
pub const MAX_GAP_S: f64 = 0.1;

/// The unit quaternion turning by `v` (axis times angle, radians).
#[must_use]
pub fn quat_from_rotation_vector(v: DVec3) -> DQuat {
    let angle = v.length();
    if angle < 1e-12 {
        // First order: exact to the rounding at this size.
        DQuat::from_xyzw(0.5 * v.x, 0.5 * v.y, 0.5 * v.z, 1.0).normalize()
    } else {
        quat_from_axis_angle(v / angle, angle)
    }
}

/// The rotation vector (axis times angle, radians, angle in [0, pi]) of a
/// unit quaternion.
#[must_use]
pub fn rotation_vector(q: DQuat) -> DVec3 {
    // q and -q are the same rotation; w >= 0 picks the angle <= pi.
    let q = if q.w < 0.0 { -q } else { q };
    let v = DVec3::new(q.x, q.y, q.z);
    let s = v.length();
    if s < 1e-12 {
        2.0 * v
    } else {
        v * (2.0 * libm::atan2(s, q.w) / s)
    }
}

/// The gyro rate at `t` (seconds, IMU clock), rad/s in the device frame,
/// linearly interpolated between the samples around it (`samples` in time
/// order).
pub fn gyro_at(samples: &[ImuSample], t: f64) -> Result<DVec3, ImuError> {
    check_covered(samples, t, t)?;
    let after = samples.partition_point(|s| s.time_s <= t);
    Ok(
        match (
            after.checked_sub(1).and_then(|i| samples.get(i)),
            samples.get(after),
        ) {
            (Some(a), Some(b)) => interpolate(a, b, t)?,
            (Some(a), None) => a.gyro_radps,
            (None, Some(b)) => b.gyro_radps,
            (None, None) => DVec3::ZERO,
        },
    )
}

/// The device's rotation from time `t1` to time `t0` (seconds, IMU clock):
/// `device_t0_from_device_t1`, which maps a vector in the device frame at
/// `t1` into the device frame at `t0`. The gyro's rates, less `bias_radps`
/// (rad/s, device frame), are interpolated linearly between the samples
/// (`samples` in time order) and integrated by the midpoint rule. `t1`
/// before `t0` gives the inverse rotation.
pub fn integrate_gyro(
    samples: &[ImuSample],
    t0: f64,
    t1: f64,
    bias_radps: DVec3,
) -> Result<DQuat, ImuError> {
    if t1 < t0 {
        return integrate_gyro(samples, t1, t0, bias_radps).map(|q| q.inverse());
    }
    check_covered(samples, t0, t1)?;
    // The first sample after t0; the one before it is at or before t0.
    let first_after = samples.partition_point(|s| s.time_s <= t0);
    let Some(before) = first_after.checked_sub(1).and_then(|i| samples.get(i)) else {
        return Err(not_covered(samples, t0, t1));
    };
    let mut rotation = DQuat::IDENTITY;
    let mut previous = *before;
    let mut from = (t0, before.gyro_radps);
    if let Some(next) = samples.get(first_after) {
        from.1 = interpolate(before, next, t0)?;
    }
    let turn = |rotation: DQuat, (ta, wa): (f64, DVec3), (tb, wb): (f64, DVec3)| {
        let mean = 0.5 * (wa + wb) - bias_radps;
        (rotation * quat_from_rotation_vector(mean * (tb - ta))).normalize()
    };
    for sample in samples.get(first_after..).unwrap_or_default() {
        if sample.time_s >= t1 {
            let end = (t1, interpolate(&previous, sample, t1)?);
            return Ok(turn(rotation, from, end));
        }
        check_gap(&previous, sample)?;
        let here = (sample.time_s, sample.gyro_radps);
        rotation = turn(rotation, from, here);
        from = here;
        previous = *sample;
    }
    // t1 is the last sample's time exactly (check_covered).
    Ok(turn(rotation, from, (t1, previous.gyro_radps)))
}

/// The gyro integrated once over a stretch of samples, for the many
/// rotations between times inside it that the calibration asks for: the
/// device's rotation from each sample's time to the first's
/// (`device_first_from_device_k`, bias not taken off), and within a piece
/// the same midpoint rule as [`integrate_gyro`] (the two differ by the
/// commutator of a piece's parts, below 1e-9 rad at a hand's rates). Gaps
/// between the two times are not checked: [`integrate_gyro`] over the
/// stretch checks them first.
#[derive(Debug, Clone)]
pub(crate) struct GyroIntegral<'a> {
    samples: &'a [ImuSample],
    prefix: Vec<DQuat>,
}

impl<'a> GyroIntegral<'a> {
    /// The integral over `samples` (in time order).
    pub(crate) fn new(samples: &'a [ImuSample]) -> Self {
        let mut prefix = Vec::with_capacity(samples.len());
        let mut q = DQuat::IDENTITY;
        if !samples.is_empty() {
            prefix.push(q);
        }
        for w in samples.windows(2) {
            let mean = 0.5 * (w[0].gyro_radps + w[1].gyro_radps);
            q = (q * quat_from_rotation_vector(mean * (w[1].time_s - w[0].time_s))).normalize();
            prefix.push(q);
        }
        Self { samples, prefix }
    }

    /// `device_t0_from_device_t1` (seconds, IMU clock).
    pub(crate) fn rotation(&self, t0: f64, t1: f64) -> Result<DQuat, ImuError> {
        Ok((self.at(t0)?.inverse() * self.at(t1)?).normalize())
    }

    /// `device_first_from_device_t`.
    fn at(&self, t: f64) -> Result<DQuat, ImuError> {
        check_covered(self.samples, t, t)?;
        let k = self
            .samples
            .partition_point(|s| s.time_s <= t)
            .saturating_sub(1);
        let (Some(a), Some(&start)) = (self.samples.get(k), self.prefix.get(k)) else {
            return Err(not_covered(self.samples, t, t));
        };
        let Some(b) = self.samples.get(k + 1) else {
            return Ok(start);
        };
        let partial = 0.5 * (a.gyro_radps + interpolate(a, b, t)?) * (t - a.time_s);
        Ok(start * quat_from_rotation_vector(partial))
    }
}

/// The rate at `t` on the straight line between samples `a` and `b`.
fn interpolate(a: &ImuSample, b: &ImuSample, t: f64) -> Result<DVec3, ImuError> {
    check_gap(a, b)?;
    let span = b.time_s - a.time_s;
    if span <= 0.0 {
        return Ok(b.gyro_radps);
    }
    let f = ((t - a.time_s) / span).clamp(0.0, 1.0);
    Ok(a.gyro_radps + (b.gyro_radps - a.gyro_radps) * f)
}

fn check_gap(a: &ImuSample, b: &ImuSample) -> Result<(), ImuError> {
    let gap_s = b.time_s - a.time_s;
    if gap_s > MAX_GAP_S {
        return Err(ImuError::Gap {
            at_s: a.time_s,
            gap_s,
            max_gap_s: MAX_GAP_S,
        });
    }
    Ok(())
}

fn check_covered(samples: &[ImuSample], t0: f64, t1: f64) -> Result<(), ImuError> {
    match (samples.first(), samples.last()) {
        (Some(first), Some(last))
            if t0.is_finite() && t1.is_finite() && first.time_s <= t0 && t1 <= last.time_s =>
        {
            Ok(())
        }
        _ => Err(not_covered(samples, t0, t1)),
    }
}

fn not_covered(samples: &[ImuSample], from_s: f64, to_s: f64) -> ImuError {
    ImuError::NotCovered {
        from_s,
        to_s,
        first_s: samples.first().map_or(f64::NAN, |s| s.time_s),
        last_s: samples.last().map_or(f64::NAN, |s| s.time_s),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(time_s: f64, gyro_radps: DVec3) -> ImuSample {
        ImuSample {
            time_s,
            accel_mps2: DVec3::new(0.0, 9.81, 0.0),
            gyro_radps,
        }
    }

    #[test]
    fn a_constant_rate_turns_by_rate_times_time_whatever_the_ends() {
        let w = DVec3::new(0.3, -1.2, 0.7);
        let samples: Vec<_> = (0..50).map(|i| sample(f64::from(i) * 0.01, w)).collect();
        let q = integrate_gyro(&samples, 0.0137, 0.2921, DVec3::ZERO).unwrap();
        let expected = w * (0.2921 - 0.0137);
        assert!((rotation_vector(q) - expected).length() < 1e-12);
        let back = integrate_gyro(&samples, 0.2921, 0.0137, DVec3::ZERO).unwrap();
        assert!((rotation_vector(back) + expected).length() < 1e-12);
        // The bias is taken off the rate.
        let q = integrate_gyro(&samples, 0.1, 0.3, w).unwrap();
        assert!(rotation_vector(q).length() < 1e-12);
    }

    #[test]
    fn a_rate_growing_about_one_axis_integrates_to_its_area() {
        // Rate 2t about z: the angle from a to b is b^2 - a^2.
        let samples: Vec<_> = (0..=100)
            .map(|i| sample(f64::from(i) * 0.01, DVec3::Z * (0.02 * f64::from(i))))
            .collect();
        let (a, b) = (0.123, 0.877);
        let q = integrate_gyro(&samples, a, b, DVec3::ZERO).unwrap();
        assert!((rotation_vector(q).z - (b * b - a * a)).abs() < 1e-12);
        assert!((gyro_at(&samples, 0.555).unwrap().z - 1.11).abs() < 1e-12);
    }

    #[test]
    fn uncovered_intervals_and_gaps_are_errors() {
        let samples = [
            sample(0.0, DVec3::X),
            sample(0.01, DVec3::X),
            sample(0.5, DVec3::X),
        ];
        assert!(matches!(
            integrate_gyro(&samples, -0.01, 0.005, DVec3::ZERO),
            Err(ImuError::NotCovered { .. })
        ));
        assert!(matches!(
            integrate_gyro(&samples, 0.0, 0.2, DVec3::ZERO),
            Err(ImuError::Gap { .. })
        ));
        assert!(matches!(
            integrate_gyro(&[], 0.0, 0.0, DVec3::ZERO),
            Err(ImuError::NotCovered { .. })
        ));
        assert!(integrate_gyro(&samples, 0.0, f64::NAN, DVec3::ZERO).is_err());
        let q = integrate_gyro(&samples, 0.0, 0.01, DVec3::ZERO).unwrap();
        assert!((rotation_vector(q).x - 0.01).abs() < 1e-15);
    }

    #[test]
    fn the_prefix_integral_agrees_with_integrating_each_interval() {
        let samples: Vec<_> = (0..200)
            .map(|i| {
                let t = f64::from(i) * 0.01;
                sample(
                    t,
                    DVec3::new(libm::sin(3.0 * t), 0.5 * libm::cos(2.0 * t), 0.8 - t),
                )
            })
            .collect();
        let integral = GyroIntegral::new(&samples);
        for (a, b) in [(0.0, 1.99), (0.123, 0.1567), (1.5, 1.5), (0.731, 0.2)] {
            let direct = integrate_gyro(&samples, a, b, DVec3::ZERO).unwrap();
            let prefix = integral.rotation(a, b).unwrap();
            let error = rotation_vector(direct.inverse() * prefix).length();
            assert!(error < 1e-6, "{a} {b}: {error}");
        }
        assert!(integral.rotation(-0.1, 0.5).is_err());
    }

    #[test]
    fn rotation_vectors_round_trip() {
        for v in [
            DVec3::new(1e-14, 0.0, -2e-14),
            DVec3::new(0.3, -0.2, 0.1),
            DVec3::new(-2.0, 1.0, 1.5),
        ] {
            assert!((rotation_vector(quat_from_rotation_vector(v)) - v).length() < 1e-12);
        }
    }
}
