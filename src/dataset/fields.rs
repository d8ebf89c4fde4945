//! Numbers read in order from a recorded message's bytes: what ROS1's
//! serialisation and ROS2's CDR share once each has found a field's bytes
//! (its own alignment, byte order and bounds checks).

/// A reader of a message's fixed-size fields, in order.
pub(crate) trait FieldReader {
    /// What a message too short for its fields gives.
    type Error;

    /// The next field's `N` bytes in little-endian order; `what` names the
    /// field in the error.
    fn array<const N: usize>(&mut self, what: &str) -> Result<[u8; N], Self::Error>;

    /// A `uint8`.
    fn u8(&mut self, what: &str) -> Result<u8, Self::Error> {
        Ok(self.array::<1>(what)?[0])
    }

    /// A `uint32`.
    fn u32(&mut self, what: &str) -> Result<u32, Self::Error> {
        Ok(u32::from_le_bytes(self.array(what)?))
    }

    /// A `float32`.
    fn f32(&mut self, what: &str) -> Result<f32, Self::Error> {
        Ok(f32::from_le_bytes(self.array(what)?))
    }

    /// A `float64`.
    fn f64(&mut self, what: &str) -> Result<f64, Self::Error> {
        Ok(f64::from_le_bytes(self.array(what)?))
    }

    /// `N` `float64`s (a fixed-size array).
    fn f64s<const N: usize>(&mut self, what: &str) -> Result<[f64; N], Self::Error> {
        let mut out = [0.0; N];
        for v in &mut out {
            *v = self.f64(what)?;
        }
        Ok(out)
    }
}
