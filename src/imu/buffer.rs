//! The samples a pipeline keeps: checked on the way in, in time order, at
//! most a bounded number.

use super::{ImuError, ImuSample};

/// The most samples an [`ImuBuffer`] keeps (older ones are dropped): 327 s
/// of a 100 Hz IMU, 82 s at 400 Hz, far more than the few frames a
/// rotation is predicted over and the first seconds it is calibrated on.
pub const MAX_BUFFERED_SAMPLES: usize = 1 << 15;

/// IMU samples in time order (IMU clock, seconds), at most
/// [`MAX_BUFFERED_SAMPLES`] of them (a few more between trims).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ImuBuffer {
    samples: Vec<ImuSample>,
}

impl ImuBuffer {
    /// Appends `batch` after the samples kept. Refused whole, the buffer
    /// unchanged, when a sample is not finite or is earlier than the one
    /// before it (samples at the same time are kept: the rate between
    /// them is not interpolated). The oldest samples go once more than
    /// [`MAX_BUFFERED_SAMPLES`] are kept.
    pub fn push(&mut self, batch: &[ImuSample]) -> Result<(), ImuError> {
        let mut previous = self.samples.last().map(|s| s.time_s);
        for (index, sample) in batch.iter().enumerate() {
            if !sample.is_finite() {
                return Err(ImuError::NotFinite {
                    index,
                    time_s: sample.time_s,
                });
            }
            if let Some(previous_s) = previous.filter(|&p| sample.time_s < p) {
                return Err(ImuError::OutOfOrder {
                    index,
                    time_s: sample.time_s,
                    previous_s,
                });
            }
            previous = Some(sample.time_s);
        }
        self.samples.extend_from_slice(batch);
        // Trimmed in steps of a quarter so that a sample is moved at most
        // a few times, not on every push.
        if self.samples.len() > MAX_BUFFERED_SAMPLES + MAX_BUFFERED_SAMPLES / 4 {
            let excess = self.samples.len() - MAX_BUFFERED_SAMPLES;
            self.samples.drain(..excess);
        }
        Ok(())
    }

    /// The samples kept, in time order.
    #[must_use]
    pub fn samples(&self) -> &[ImuSample] {
        &self.samples
    }

    /// Forgets every sample.
    pub fn clear(&mut self) {
        self.samples.clear();
    }

    /// The mean sample rate of the samples kept, Hz; `None` with fewer
    /// than two samples or no time between them.
    #[must_use]
    pub fn rate_hz(&self) -> Option<f64> {
        let (first, last) = (self.samples.first()?, self.samples.last()?);
        let span = last.time_s - first.time_s;
        (span > 0.0).then(|| (self.samples.len() - 1) as f64 / span)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    fn at(time_s: f64) -> ImuSample {
        ImuSample {
            time_s,
            accel_mps2: DVec3::Y,
            gyro_radps: DVec3::ZERO,
        }
    }

    #[test]
    fn bad_batches_leave_it_unchanged_and_it_stays_bounded() {
        let mut buffer = ImuBuffer::default();
        buffer.push(&[at(0.0), at(0.01)]).unwrap();
        let nan = ImuSample {
            gyro_radps: DVec3::new(0.0, f64::NAN, 0.0),
            ..at(0.02)
        };
        assert!(matches!(
            buffer.push(&[at(0.02), nan]),
            Err(ImuError::NotFinite { index: 1, .. })
        ));
        assert!(matches!(
            buffer.push(&[at(0.005)]),
            Err(ImuError::OutOfOrder { index: 0, .. })
        ));
        assert!(matches!(
            buffer.push(&[at(0.03), at(0.02)]),
            Err(ImuError::OutOfOrder { index: 1, .. })
        ));
        assert_eq!(buffer.samples().len(), 2);
        let many: Vec<_> = (2..3 * MAX_BUFFERED_SAMPLES)
            .map(|i| at(i as f64 * 0.01))
            .collect();
        for chunk in many.chunks(1000) {
            buffer.push(chunk).unwrap();
            assert!(buffer.samples().len() <= MAX_BUFFERED_SAMPLES * 5 / 4);
        }
        assert!((buffer.rate_hz().unwrap() - 100.0).abs() < 1e-6);
        buffer.clear();
        assert!(buffer.samples().is_empty() && buffer.rate_hz().is_none());
    }
}
