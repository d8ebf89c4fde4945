//! The ROS1 messages a RealSense recording needs, deserialised from their
//! bytes (little-endian; strings and arrays prefixed by a u32 count):
//! `sensor_msgs/Image` (its head and where its pixels lie),
//! `sensor_msgs/CameraInfo`, `geometry_msgs/Transform`, `std_msgs/Float32`,
//! `sensor_msgs/Imu`. Every count is checked against the bytes left; bytes
//! after the fields read are ignored (librealsense appends to some).

use super::RosbagError;
use crate::dataset::fields::FieldReader;

/// Reads fields in order from a message's bytes; errors name `topic`.
struct Cursor<'a> {
    bytes: &'a [u8],
    at: usize,
    topic: &'a str,
}

impl<'a> Cursor<'a> {
    fn new(bytes: &'a [u8], topic: &'a str) -> Self {
        Self {
            bytes,
            at: 0,
            topic,
        }
    }

    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], RosbagError> {
        let out = self
            .at
            .checked_add(n)
            .and_then(|end| self.bytes.get(self.at..end))
            .ok_or_else(|| RosbagError::Message {
                topic: self.topic.to_owned(),
                reason: format!(
                    "the message ends in its {what} ({} bytes, {n} more needed at byte {})",
                    self.bytes.len(),
                    self.at
                ),
            })?;
        self.at += n;
        Ok(out)
    }

    fn string(&mut self, what: &str) -> Result<String, RosbagError> {
        let n = self.u32(what)? as usize;
        Ok(String::from_utf8_lossy(self.take(n, what)?).into_owned())
    }

    /// A `time`: u32 seconds, u32 nanoseconds, as seconds.
    fn time(&mut self, what: &str) -> Result<f64, RosbagError> {
        let sec = self.u32(what)?;
        let nsec = self.u32(what)?;
        Ok(f64::from(sec) + f64::from(nsec) * 1e-9)
    }

    /// A `std_msgs/Header` (seq, stamp, frame_id): its stamp, seconds.
    fn header(&mut self) -> Result<f64, RosbagError> {
        self.u32("header")?;
        let stamp = self.time("header")?;
        self.string("header's frame_id")?;
        Ok(stamp)
    }
}

impl FieldReader for Cursor<'_> {
    type Error = RosbagError;

    fn array<const N: usize>(&mut self, what: &str) -> Result<[u8; N], Self::Error> {
        let bytes = self.take(N, what)?;
        let mut out = [0u8; N];
        out.copy_from_slice(bytes);
        Ok(out)
    }
}

/// A `sensor_msgs/Image` without its pixels: what they are and where.
#[derive(Debug, Clone, PartialEq)]
pub struct ImageHead {
    /// The header's stamp, seconds (the camera's clock).
    pub stamp_s: f64,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// Pixel encoding (`mono16`, `16UC1`, `rgb8`, `bgr8`, `rgba8`, `bgra8`, ...).
    pub encoding: String,
    /// Whether multi-byte pixels are big-endian.
    pub big_endian: bool,
    /// Bytes per row.
    pub step: u32,
    /// Where the pixels start in the message, bytes.
    pub data_offset: usize,
    /// The pixels' length, bytes (within the message).
    pub data_len: usize,
}

/// Reads a `sensor_msgs/Image`'s head from its bytes.
pub(crate) fn image_head(bytes: &[u8], topic: &str) -> Result<ImageHead, RosbagError> {
    let mut c = Cursor::new(bytes, topic);
    let stamp_s = c.header()?;
    let height = c.u32("height")?;
    let width = c.u32("width")?;
    let encoding = c.string("encoding")?;
    let big_endian = c.u8("is_bigendian")? != 0;
    let step = c.u32("step")?;
    let data_len = c.u32("data")? as usize;
    let data_offset = c.at;
    c.take(data_len, "pixels")?;
    Ok(ImageHead {
        stamp_s,
        height,
        width,
        encoding,
        big_endian,
        step,
        data_offset,
        data_len,
    })
}

/// A `sensor_msgs/CameraInfo`: the image size, the distortion model and
/// its coefficients, the intrinsic matrix.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraInfo {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// The distortion model's name (`Brown Conrady`, `Inverse Brown
    /// Conrady`, `plumb_bob`, ...).
    pub distortion_model: String,
    /// Distortion coefficients (k1, k2, p1, p2, k3 for Brown-Conrady).
    pub d: Vec<f64>,
    /// The 3x3 intrinsic matrix, row-major `[fx, 0, cx, 0, fy, cy, 0, 0, 1]`, pixels.
    pub k: [f64; 9],
}

/// Reads a `sensor_msgs/CameraInfo` (the fields after `K` are not needed).
pub(crate) fn camera_info(bytes: &[u8], topic: &str) -> Result<CameraInfo, RosbagError> {
    let mut c = Cursor::new(bytes, topic);
    c.header()?;
    let height = c.u32("height")?;
    let width = c.u32("width")?;
    let distortion_model = c.string("distortion_model")?;
    let n = c.u32("D")? as usize;
    if n > 64 {
        return Err(RosbagError::Message {
            topic: topic.to_owned(),
            reason: format!("{n} distortion coefficients"),
        });
    }
    let d = (0..n).map(|_| c.f64("D")).collect::<Result<_, _>>()?;
    let k = c.f64s("K")?;
    Ok(CameraInfo {
        width,
        height,
        distortion_model,
        d,
        k,
    })
}

/// A `geometry_msgs/Transform`: translation (metres) and rotation
/// quaternion `[x, y, z, w]`.
pub(crate) fn transform(bytes: &[u8], topic: &str) -> Result<([f64; 3], [f64; 4]), RosbagError> {
    let mut c = Cursor::new(bytes, topic);
    Ok((c.f64s("translation")?, c.f64s("rotation")?))
}

/// A `std_msgs/Float32`'s value.
pub(crate) fn float32(bytes: &[u8], topic: &str) -> Result<f32, RosbagError> {
    Cursor::new(bytes, topic).f32("data")
}

/// A `sensor_msgs/Imu`: stamp (seconds), angular velocity (rad/s) and
/// linear acceleration (m/s^2), in the IMU's frame.
pub(crate) fn imu(bytes: &[u8], topic: &str) -> Result<(f64, [f64; 3], [f64; 3]), RosbagError> {
    let mut c = Cursor::new(bytes, topic);
    let stamp = c.header()?;
    c.f64s::<4>("orientation")?;
    c.f64s::<9>("orientation_covariance")?;
    let gyro = c.f64s("angular_velocity")?;
    c.f64s::<9>("angular_velocity_covariance")?;
    let accel = c.f64s("linear_acceleration")?;
    Ok((stamp, gyro, accel))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image_bytes(encoding: &str, pixels: &[u8]) -> Vec<u8> {
        let mut b = Vec::new();
        b.extend(7u32.to_le_bytes());
        b.extend(12u32.to_le_bytes());
        b.extend(500_000_000u32.to_le_bytes());
        b.extend(1u32.to_le_bytes());
        b.push(b'0');
        b.extend(1u32.to_le_bytes()); // height
        b.extend(2u32.to_le_bytes()); // width
        b.extend((encoding.len() as u32).to_le_bytes());
        b.extend(encoding.as_bytes());
        b.push(0);
        b.extend(4u32.to_le_bytes());
        b.extend((pixels.len() as u32).to_le_bytes());
        b.extend(pixels);
        b
    }

    #[test]
    fn image_head_reads_and_every_cut_is_an_error() {
        let bytes = image_bytes("mono16", &[1, 0, 2, 0]);
        let head = image_head(&bytes, "t").expect("reads");
        assert_eq!(head.stamp_s, 12.5);
        assert_eq!((head.width, head.height, head.step), (2, 1, 4));
        assert_eq!(head.encoding, "mono16");
        assert_eq!(&bytes[head.data_offset..][..head.data_len], &[1, 0, 2, 0]);
        for cut in 0..bytes.len() {
            let err = image_head(&bytes[..cut], "t").expect_err("cut");
            assert!(matches!(err, RosbagError::Message { .. }), "{err:?}");
        }
        let mut huge = bytes.clone();
        let n = huge.len();
        huge[n - 8..n - 4].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(image_head(&huge, "t").is_err(), "a forged pixel count");
    }
}
