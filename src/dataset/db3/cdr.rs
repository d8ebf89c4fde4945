//! The ROS2 messages a RealSense `.db3` needs, deserialised from CDR (a
//! 4-byte encapsulation header, then fields aligned to their size from
//! there; strings and sequences prefixed by a u32 count; little- or
//! big-endian as the header says): `std_msgs/String` (librealsense's
//! `key=value;...` records), `sensor_msgs/CompressedImage`,
//! `sensor_msgs/CameraInfo`, `sensor_msgs/Imu`. Every count is checked
//! against the bytes left; padding bytes are not read (the recorder leaves
//! them uninitialised).

use super::Db3Error;
use crate::dataset::fields::FieldReader;
use crate::dataset::rosbag::CameraInfo;

/// Reads fields in order from a message's bytes; errors name `topic`.
struct Cursor<'a> {
    body: &'a [u8],
    at: usize,
    little: bool,
    topic: &'a str,
}

impl<'a> Cursor<'a> {
    fn new(bytes: &'a [u8], topic: &'a str) -> Result<Self, Db3Error> {
        let bad = |reason: String| Db3Error::Message {
            topic: topic.to_owned(),
            reason,
        };
        let head = bytes
            .get(..4)
            .ok_or_else(|| bad(format!("{} bytes, no CDR header", bytes.len())))?;
        // 0x0000 CDR_BE, 0x0001 CDR_LE (XCDR1); XCDR2 plain is 0x0006/0x0007.
        let little = match (head[0], head[1]) {
            (0, 0) | (0, 6) => false,
            (0, 1) | (0, 7) => true,
            (a, b) => return Err(bad(format!("an unknown CDR encapsulation {a:#04x}{b:02x}"))),
        };
        Ok(Self {
            body: &bytes[4..],
            at: 0,
            little,
            topic,
        })
    }

    fn fail(&self, what: &str, n: usize) -> Db3Error {
        Db3Error::Message {
            topic: self.topic.to_owned(),
            reason: format!(
                "the message ends in its {what} ({} bytes, {n} more needed at byte {})",
                self.body.len() + 4,
                self.at + 4
            ),
        }
    }

    fn align(&mut self, n: usize) {
        self.at = self.at.div_ceil(n) * n;
    }

    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], Db3Error> {
        let out = self
            .at
            .checked_add(n)
            .and_then(|end| self.body.get(self.at..end))
            .ok_or_else(|| self.fail(what, n))?;
        self.at += n;
        Ok(out)
    }

    /// A string: its bytes without the terminating NUL.
    fn string(&mut self, what: &str) -> Result<String, Db3Error> {
        let n = self.u32(what)? as usize;
        let bytes = self.take(n, what)?;
        let text = bytes.strip_suffix(&[0]).unwrap_or(bytes);
        Ok(String::from_utf8_lossy(text).into_owned())
    }

    /// A `builtin_interfaces/Time` (i32 seconds, u32 nanoseconds), seconds.
    fn time(&mut self, what: &str) -> Result<f64, Db3Error> {
        let sec = self.u32(what)? as i32;
        let nsec = self.u32(what)?;
        Ok(f64::from(sec) + f64::from(nsec) * 1e-9)
    }

    /// A `std_msgs/Header` (stamp, frame_id): its stamp, seconds.
    fn header(&mut self) -> Result<f64, Db3Error> {
        let stamp = self.time("header")?;
        self.string("header's frame_id")?;
        Ok(stamp)
    }
}

impl FieldReader for Cursor<'_> {
    type Error = Db3Error;

    fn array<const N: usize>(&mut self, what: &str) -> Result<[u8; N], Self::Error> {
        self.align(N);
        let mut out = [0u8; N];
        out.copy_from_slice(self.take(N, what)?);
        if !self.little {
            out.reverse();
        }
        Ok(out)
    }
}

/// A `std_msgs/String`'s text.
pub fn string(bytes: &[u8], topic: &str) -> Result<String, Db3Error> {
    Cursor::new(bytes, topic)?.string("data")
}

/// The value of `key` in librealsense's `key=value;key=value` text.
#[must_use]
pub fn field<'a>(text: &'a str, key: &str) -> Option<&'a str> {
    text.split(';')
        .filter_map(|kv| kv.split_once('='))
        .find(|(k, _)| k.trim() == key)
        .map(|(_, v)| v.trim())
}

/// A `sensor_msgs/CompressedImage` without its bytes: its stamp, its
/// `format` and where its data lie in the message.
#[derive(Debug, Clone, PartialEq)]
pub struct CompressedHead {
    /// The header's stamp, seconds.
    pub stamp_s: f64,
    /// The format (`16UC1; compressedDepth png`, `rgb8; png compressed bgr8`, ...).
    pub format: String,
    /// Where the data start in the message, bytes.
    pub data_offset: usize,
    /// The data's length, bytes (the message may hold fewer when only its
    /// first bytes were read).
    pub data_len: usize,
}

/// Reads a `sensor_msgs/CompressedImage`'s head from (the first bytes of) its message.
pub fn compressed_head(bytes: &[u8], topic: &str) -> Result<CompressedHead, Db3Error> {
    let mut c = Cursor::new(bytes, topic)?;
    let stamp_s = c.header()?;
    let format = c.string("format")?;
    let data_len = c.u32("data")? as usize;
    Ok(CompressedHead {
        stamp_s,
        format,
        data_offset: c.at + 4,
        data_len,
    })
}

/// Reads a `sensor_msgs/CameraInfo` (the fields after `k` are not needed).
pub fn camera_info(bytes: &[u8], topic: &str) -> Result<CameraInfo, Db3Error> {
    let mut c = Cursor::new(bytes, topic)?;
    c.header()?;
    let height = c.u32("height")?;
    let width = c.u32("width")?;
    let distortion_model = c.string("distortion_model")?;
    let n = c.u32("d")? as usize;
    if n > 64 {
        return Err(Db3Error::Message {
            topic: topic.to_owned(),
            reason: format!("{n} distortion coefficients"),
        });
    }
    let d = (0..n).map(|_| c.f64("d")).collect::<Result<_, _>>()?;
    let k = c.f64s("k")?;
    Ok(CameraInfo {
        width,
        height,
        distortion_model,
        d,
        k,
    })
}

/// A `sensor_msgs/Imu`: stamp (seconds), angular velocity (rad/s) and
/// linear acceleration (m/s^2), in the IMU's frame.
pub fn imu(bytes: &[u8], topic: &str) -> Result<(f64, [f64; 3], [f64; 3]), Db3Error> {
    let mut c = Cursor::new(bytes, topic)?;
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

    /// A CompressedImage as the recorder writes it (padding bytes not zero).
    fn compressed(format: &str, data: &[u8]) -> Vec<u8> {
        let mut b = vec![0, 1, 0, 0];
        b.extend(3i32.to_le_bytes());
        b.extend(500_000_000u32.to_le_bytes());
        b.extend(6u32.to_le_bytes());
        b.extend(b"Depth\0xx");
        b.extend((format.len() as u32 + 1).to_le_bytes());
        b.extend(format.as_bytes());
        b.push(0);
        while (b.len() - 4) % 4 != 0 {
            b.push(b'm');
        }
        b.extend((data.len() as u32).to_le_bytes());
        b.extend(data);
        b
    }

    #[test]
    fn compressed_head_reads_and_every_cut_is_an_error() {
        let bytes = compressed("16UC1; compressedDepth png", &[9, 8, 7]);
        let head = compressed_head(&bytes, "t").expect("reads");
        assert_eq!(head.stamp_s, 3.5);
        assert_eq!(head.format, "16UC1; compressedDepth png");
        assert_eq!(&bytes[head.data_offset..][..head.data_len], &[9, 8, 7]);
        for cut in 0..head.data_offset {
            assert!(compressed_head(&bytes[..cut], "t").is_err(), "cut at {cut}");
        }
        let mut other = bytes.clone();
        other[1] = 9;
        assert!(
            compressed_head(&other, "t").is_err(),
            "an unknown encapsulation"
        );
    }

    #[test]
    fn librealsense_fields() {
        let text = "Frame number=1;timestamp=32.103062;depth_units=0.000200;";
        assert_eq!(field(text, "timestamp"), Some("32.103062"));
        assert_eq!(field(text, "depth_units"), Some("0.000200"));
        assert_eq!(field(text, "fps"), None);
    }
}
