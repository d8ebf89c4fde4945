//! A simulated IMU riding on a known camera path: the gyro reads the path's
//! rate of turn, the accelerometer its specific force, in a device frame
//! mounted at a fixed rotation from the camera's, stamped on a clock that
//! runs a fixed offset ahead of the frames', with white noise and a
//! constant bias.
//!
//! The IMU sits at the camera's optical centre (a phone's is a centimetre
//! or two away: the lever arm adds centripetal terms to the accelerometer
//! that are left out). Gravity points along world +y in the synthetic room
//! (world -y is up).

use glam::{DAffine3, DMat3, DQuat, DVec3};

use crate::imu::{rotation_vector, ImuSample};
use crate::random::SplitMix;

/// Standard gravity, m/s².
pub const STANDARD_GRAVITY_MPS2: f64 = 9.806_65;

/// How the IMU is simulated. Rates rad/s, accelerations m/s², times
/// seconds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuSimulation {
    /// Samples per second, Hz.
    pub rate_hz: f64,
    /// The gyro's white noise density, rad/s/sqrt(Hz): a sample's sigma is
    /// this times sqrt(`rate_hz`).
    pub gyro_noise_density: f64,
    /// The accelerometer's white noise density, m/s²/sqrt(Hz).
    pub accel_noise_density: f64,
    /// The gyro's constant bias, rad/s, device frame.
    pub gyro_bias_radps: DVec3,
    /// The accelerometer's constant bias, m/s², device frame.
    pub accel_bias_mps2: DVec3,
    /// The device's axes in the camera frame (`camera_from_imu * v_imu` is
    /// `v_imu` in camera coordinates).
    pub camera_from_imu: DQuat,
    /// Seconds the IMU's clock runs ahead of the frames': a sample stamped
    /// `t` was measured at frame time `t - time_offset_s`.
    pub time_offset_s: f64,
    /// Gravity in the world frame, m/s² (the room's: along +y).
    pub gravity_world_mps2: DVec3,
    /// Seed of the noise.
    pub seed: u64,
}

impl Default for ImuSimulation {
    /// [`Self::phone`].
    fn default() -> Self {
        Self::phone()
    }
}

impl ImuSimulation {
    /// A phone's IMU at 100 Hz (Stray Scanner's `imu.csv` rate). Noise
    /// densities from the Bosch BMI160 datasheet (BST-BMI160-DS000, a
    /// smartphone IMU): gyro 0.007 deg/s/sqrt(Hz) (1.22e-4 rad/s/sqrt(Hz)),
    /// accelerometer 180 ug/sqrt(Hz) (1.77e-3 m/s²/sqrt(Hz)). Biases: the
    /// datasheet's zero-rate offset is ±3 deg/s before the phone's own
    /// calibration; what is left after it is taken as about 0.25 deg/s
    /// (4e-3 rad/s) a gyro axis and 10-15 mg an accelerometer axis (the
    /// datasheet's zero-g offset: ±40 mg). Mounted as an iPhone's: device
    /// x along camera -y, device y along camera -x, device z along camera
    /// -z (the back camera looks out of the screen's back). Clock 10 ms
    /// ahead of the frames'.
    #[must_use]
    pub fn phone() -> Self {
        Self {
            rate_hz: 100.0,
            gyro_noise_density: 0.007_f64.to_radians(),
            accel_noise_density: 180e-6 * STANDARD_GRAVITY_MPS2,
            gyro_bias_radps: DVec3::new(0.004, -0.003, 0.0045),
            accel_bias_mps2: DVec3::new(0.12, -0.09, 0.15),
            camera_from_imu: DQuat::from_mat3(&DMat3::from_cols(
                DVec3::new(0.0, -1.0, 0.0),
                DVec3::new(-1.0, 0.0, 0.0),
                DVec3::new(0.0, 0.0, -1.0),
            )),
            time_offset_s: 0.010,
            gravity_world_mps2: DVec3::new(0.0, STANDARD_GRAVITY_MPS2, 0.0),
            seed: 1,
        }
    }

    /// The samples of the IMU riding on `world_from_camera` (a pose for
    /// each time in seconds on the frames' clock, metres) between frame
    /// times `first_s` and `last_s`: stamped every `1 / rate_hz` s on the
    /// IMU's clock, at whole multiples of the interval. The rates come
    /// from central differences of the path 1 ms either side of each
    /// sample's instant.
    #[must_use]
    pub fn simulate(
        &self,
        world_from_camera: impl Fn(f64) -> DAffine3,
        first_s: f64,
        last_s: f64,
    ) -> Vec<ImuSample> {
        let rate = self.rate_hz.max(1e-3);
        let first = libm::ceil((first_s + self.time_offset_s) * rate) as i64;
        let last = libm::floor((last_s + self.time_offset_s) * rate) as i64;
        let mut rng = SplitMix::new(self.seed);
        let gyro_sigma = self.gyro_noise_density * rate.sqrt();
        let accel_sigma = self.accel_noise_density * rate.sqrt();
        let camera_from_imu = DMat3::from_quat(self.camera_from_imu);
        let world_from_device = |t: f64| world_from_camera(t).matrix3 * camera_from_imu;
        let h = 1e-3;
        (first..=last)
            .map(|k| {
                let time_s = k as f64 / rate;
                let t = time_s - self.time_offset_s;
                let (before, after) = (world_from_device(t - h), world_from_device(t + h));
                let turn = DQuat::from_mat3(&(before.transpose() * after));
                let gyro = rotation_vector(turn) / (2.0 * h);
                let position = |t: f64| world_from_camera(t).translation;
                let acceleration =
                    (position(t + h) - 2.0 * position(t) + position(t - h)) / (h * h);
                let specific_force =
                    world_from_device(t).transpose() * (acceleration - self.gravity_world_mps2);
                ImuSample {
                    time_s,
                    accel_mps2: specific_force
                        + self.accel_bias_mps2
                        + gaussian3(&mut rng) * accel_sigma,
                    gyro_radps: gyro + self.gyro_bias_radps + gaussian3(&mut rng) * gyro_sigma,
                }
            })
            .collect()
    }
}

/// Three independent standard normal draws (Box-Muller).
fn gaussian3(rng: &mut SplitMix) -> DVec3 {
    let mut draw = || {
        // 1 - u lies in (0, 1]: its logarithm is finite.
        let radius = (-2.0 * libm::log(1.0 - rng.next_f64())).sqrt();
        let (s, c) = libm::sincos(std::f64::consts::TAU * rng.next_f64());
        (radius * c, radius * s)
    };
    let (x, y) = draw();
    let (z, _) = draw();
    DVec3::new(x, y, z)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::portable_math::quat_from_axis_angle;

    #[test]
    fn a_still_device_reads_gravity_up_and_a_steady_turn_its_rate() {
        let quiet = ImuSimulation {
            gyro_noise_density: 0.0,
            accel_noise_density: 0.0,
            gyro_bias_radps: DVec3::ZERO,
            accel_bias_mps2: DVec3::ZERO,
            ..ImuSimulation::phone()
        };
        // Still, camera upright: up is camera -y, which is device +x.
        let still = quiet.simulate(|_| DAffine3::IDENTITY, 0.0, 0.1);
        assert_eq!(still.len(), 11, "stamps 0.01..0.11: the 10 ms offset");
        for s in &still {
            assert!((s.accel_mps2 - DVec3::X * STANDARD_GRAVITY_MPS2).length() < 1e-6);
            assert!(s.gyro_radps.length() < 1e-9);
        }
        // Turning about camera +z at 1 rad/s: device -z.
        let turning = quiet.simulate(
            |t| DAffine3::from_quat(quat_from_axis_angle(DVec3::Z, t)),
            0.0,
            0.1,
        );
        for s in &turning {
            assert!((s.gyro_radps - DVec3::new(0.0, 0.0, -1.0)).length() < 1e-6);
        }
    }

    #[test]
    fn noise_has_the_density_asked_for() {
        let sim = ImuSimulation {
            gyro_bias_radps: DVec3::ZERO,
            ..ImuSimulation::phone()
        };
        let samples = sim.simulate(|_| DAffine3::IDENTITY, 0.0, 100.0);
        let n = samples.len() as f64;
        let var = samples
            .iter()
            .map(|s| s.gyro_radps.length_squared())
            .sum::<f64>()
            / (3.0 * n);
        let expected = sim.gyro_noise_density * sim.rate_hz.sqrt();
        assert!((var.sqrt() / expected - 1.0).abs() < 0.03, "{}", var.sqrt());
    }
}
