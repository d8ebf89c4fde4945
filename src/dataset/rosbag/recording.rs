//! A RealSense recording found in a bag's messages: the depth stream (a
//! `sensor_msgs/Image` topic of 16-bit depth, `.../Depth_0/image/data` as
//! librealsense names it), the colour stream if any, each one's
//! `camera_info` (`.../info/camera_info`) and extrinsics (`.../tf/N`, from
//! the device's reference stream N to this one), the depth units option
//! (`/device_0/sensor_0/option/Depth Units/value`, metres per unit), the
//! IMU samples; then colour paired with depth by timestamp. A ROS2 `.db3`
//! recording ([`crate::dataset::db3`]) fills the same [`Collected`] from its
//! own messages (`L`: where its messages lie) and is assembled here too.

use std::collections::HashMap;

use glam::{DAffine3, DQuat, DVec3};

use super::message::{self, CameraInfo, ImageHead};
use super::pixels::{colour_bytes_per_pixel, is_depth_encoding};
use super::register::{CameraModel, Registration};
use super::scan::{Connection, Location};
use super::RosbagError;

/// Depth units taken when the recording names none, metres (the D400's default).
pub const DEFAULT_DEPTH_UNITS_M: f64 = 0.001;

/// One IMU sample, as `sensor_msgs/Imu` carries it. librealsense records
/// the accelerometer and the gyro as two streams (`.../Accel_0/imu/data`,
/// `.../Gyro_0/imu/data`), so a sample holds one of the two; a generic
/// ROS IMU topic holds both.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuSample {
    /// The message's stamp, seconds (the camera's clock, as the frames').
    pub time_s: f64,
    /// Linear acceleration, m/s^2, IMU frame; `None` in a gyro sample.
    pub accel_mps2: Option<[f64; 3]>,
    /// Angular velocity, rad/s, IMU frame; `None` in an accelerometer sample.
    pub gyro_radps: Option<[f64; 3]>,
}

/// One frame of the recording: a depth image and, when one lies within
/// half a frame period, the colour image nearest in time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BagFrame<L = Location> {
    /// The depth image's stamp, seconds.
    pub time_s: f64,
    /// Where the depth image lies.
    pub depth: L,
    /// The colour image's stamp (seconds) and place, if paired.
    pub colour: Option<(f64, L)>,
}

/// What a recording holds; see the module documentation.
#[derive(Debug, Clone, PartialEq)]
pub struct Recording<L = Location> {
    /// The depth stream's topic.
    pub depth_topic: String,
    /// The depth camera (its intrinsics drive tracking).
    pub depth: CameraModel,
    /// Metres per depth unit (the depth units option, a float32, as the
    /// decimal it holds, or [`DEFAULT_DEPTH_UNITS_M`]).
    pub depth_units_m: f64,
    /// The colour stream's topic and its registration to depth; `None`
    /// without colour (or without its calibration).
    pub colour: Option<(String, Registration)>,
    /// Colour images in the colour stream.
    pub colour_images: usize,
    /// Frames in time order.
    pub frames: Vec<BagFrame<L>>,
    /// IMU samples in time order.
    pub imu: Vec<ImuSample>,
    /// What did not stop the recording (no depth units, colour without
    /// calibration, frames without colour).
    pub warnings: Vec<RosbagError>,
}

/// An image topic's first image and every image's stamp and place.
#[derive(Debug, Clone)]
struct ImageTopic<L> {
    first: ImageHead,
    images: Vec<(f64, L)>,
}

/// The messages a scan keeps; see [`Collected::visit`].
#[derive(Debug)]
pub(crate) struct Collected<L = Location> {
    images: HashMap<String, ImageTopic<L>>,
    camera_info: HashMap<String, CameraInfo>,
    transforms: HashMap<String, ([f64; 3], [f64; 4])>,
    depth_units: HashMap<String, f32>,
    imu: Vec<ImuSample>,
}

impl<L> Default for Collected<L> {
    fn default() -> Self {
        Self {
            images: HashMap::new(),
            camera_info: HashMap::new(),
            transforms: HashMap::new(),
            depth_units: HashMap::new(),
            imu: Vec::new(),
        }
    }
}

impl<L> Collected<L> {
    /// Keeps an image's stamp (seconds) and place; `head` describes its
    /// pixels (the first of each topic is kept).
    pub(crate) fn add_image(&mut self, topic: &str, head: ImageHead, location: L) {
        let stamp = head.stamp_s;
        self.images
            .entry(topic.to_owned())
            .or_insert_with(|| ImageTopic {
                first: head,
                images: Vec::new(),
            })
            .images
            .push((stamp, location));
    }

    /// Whether `topic`'s camera info is already kept.
    pub(crate) fn has_camera_info(&self, topic: &str) -> bool {
        self.camera_info.contains_key(topic)
    }

    /// Keeps a topic's first camera info.
    pub(crate) fn add_camera_info(&mut self, topic: &str, info: CameraInfo) {
        self.camera_info.entry(topic.to_owned()).or_insert(info);
    }

    /// Keeps a topic's first transform: translation (metres), rotation `[x, y, z, w]`.
    pub(crate) fn add_transform(&mut self, topic: &str, tf: ([f64; 3], [f64; 4])) {
        self.transforms.entry(topic.to_owned()).or_insert(tf);
    }

    /// Keeps a depth units option (metres per unit), if `topic` is one.
    pub(crate) fn add_depth_units(&mut self, topic: &str, units: f32) {
        if is_depth_units_topic(topic) {
            self.depth_units.entry(topic.to_owned()).or_insert(units);
        }
    }

    /// Keeps an IMU sample of `topic` (librealsense's `Accel`/`Gyro`
    /// streams hold one of the two vectors).
    pub(crate) fn add_imu(&mut self, topic: &str, time_s: f64, gyro: [f64; 3], accel: [f64; 3]) {
        let lower = topic.to_ascii_lowercase();
        let (is_accel, is_gyro) = (lower.contains("accel"), lower.contains("gyro"));
        self.imu.push(ImuSample {
            time_s,
            accel_mps2: (!is_gyro).then_some(accel),
            gyro_radps: (!is_accel).then_some(gyro),
        });
    }
}

impl Collected<Location> {
    /// Keeps what a message says (an image's stamp and place, not its
    /// pixels; the first camera info, transform and depth units of each
    /// topic; every IMU sample).
    pub(crate) fn visit(
        &mut self,
        conn: &Connection,
        location: Location,
        data: &[u8],
    ) -> Result<(), RosbagError> {
        let topic = conn.topic.as_str();
        match conn.msg_type.as_str() {
            "sensor_msgs/Image" => {
                let head = message::image_head(data, topic)?;
                self.add_image(topic, head, location);
            }
            "sensor_msgs/CameraInfo" if !self.camera_info.contains_key(topic) => {
                let info = message::camera_info(data, topic)?;
                self.add_camera_info(topic, info);
            }
            "geometry_msgs/Transform" if !self.transforms.contains_key(topic) => {
                let tf = message::transform(data, topic)?;
                self.add_transform(topic, tf);
            }
            "std_msgs/Float32" if is_depth_units_topic(topic) => {
                let units = message::float32(data, topic)?;
                self.add_depth_units(topic, units);
            }
            "sensor_msgs/Imu" => {
                let (time_s, gyro, accel) = message::imu(data, topic)?;
                self.add_imu(topic, time_s, gyro, accel);
            }
            _ => {}
        }
        Ok(())
    }
}

fn is_depth_units_topic(topic: &str) -> bool {
    let lower = topic.to_ascii_lowercase().replace('_', " ");
    lower.ends_with("/option/depth units/value")
}

/// An image topic's stream (`/device_0/sensor_0/Depth_0`): the topic
/// without `image/data` (ROS1) or `image/data/compressed[Depth]` (ROS2).
fn stream_of(image_topic: &str) -> &str {
    let t = image_topic.trim_end_matches('/');
    let t = t
        .strip_suffix("/compressedDepth")
        .or_else(|| t.strip_suffix("/compressed"))
        .unwrap_or(t);
    parent(t, 2)
}

/// `topic` without its last `n` components.
fn parent(topic: &str, n: usize) -> &str {
    let mut t = topic.trim_end_matches('/');
    for _ in 0..n {
        t = t.rsplit_once('/').map_or("", |(head, _)| head);
    }
    t
}

/// The topic among `candidates` whose name holds one of `names` (any
/// case), else the one with most images.
fn pick<'a, L>(
    candidates: &[(&'a String, &'a ImageTopic<L>)],
    names: &[&str],
) -> Option<&'a String> {
    let named = candidates
        .iter()
        .filter(|(t, _)| {
            let lower = t.to_ascii_lowercase();
            names.iter().any(|n| lower.contains(n))
        })
        .max_by_key(|(t, i)| (i.images.len(), std::cmp::Reverse(*t)));
    named
        .or_else(|| {
            candidates
                .iter()
                .max_by_key(|(t, i)| (i.images.len(), std::cmp::Reverse(*t)))
        })
        .map(|(t, _)| *t)
}

/// A stream's calibration: librealsense's `<stream>/info/camera_info`
/// (ROS1) or `<stream>/image/camera_info` (ROS2) beside
/// `<stream>/image/data`, or a `camera_info` beside the image topic.
fn camera_info_of<'a, L>(c: &'a Collected<L>, image_topic: &str) -> Option<&'a CameraInfo> {
    let stream = stream_of(image_topic);
    c.camera_info
        .get(&format!("{stream}/info/camera_info"))
        .or_else(|| c.camera_info.get(&format!("{stream}/image/camera_info")))
        .or_else(|| {
            c.camera_info
                .get(&format!("{}/camera_info", parent(image_topic, 1)))
        })
}

/// The extrinsics `<stream>/tf/<reference>` of the reference stream
/// `reference` (librealsense writes `tf/0` or `tf/1`, ROS2 `tf/ref_1`: the
/// id of the device's reference stream), or of the lowest reference when
/// `None`: the reference and the transform from it to this stream.
fn extrinsics_of<'a, L>(
    c: &'a Collected<L>,
    image_topic: &str,
    reference: Option<&str>,
) -> Option<(&'a str, DAffine3)> {
    let prefix = format!("{}/tf/", stream_of(image_topic));
    let (id, (t, q)) = c
        .transforms
        .iter()
        .filter_map(|(topic, tf)| Some((topic.strip_prefix(&prefix)?, tf)))
        .filter(|(id, _)| reference.is_none_or(|r| r == *id))
        .min_by_key(|(id, _)| *id)?;
    let q = DQuat::from_xyzw(q[0], q[1], q[2], q[3]);
    let t = DVec3::from_array(*t);
    (q.is_finite() && t.is_finite() && q.length() > 0.5)
        .then(|| (id, DAffine3::from_rotation_translation(q.normalize(), t)))
}

impl<L: Copy> Recording<L> {
    /// The recording in a scan's messages. Errors: no depth stream, no
    /// depth frame, no depth calibration, colour in an encoding not read.
    pub(crate) fn from_collected(mut c: Collected<L>) -> Result<Self, RosbagError> {
        let mut warnings = Vec::new();
        let topics: Vec<(&String, &ImageTopic<L>)> = c.images.iter().collect();
        let depths: Vec<_> = topics
            .iter()
            .copied()
            .filter(|(_, i)| is_depth_encoding(&i.first.encoding))
            .collect();
        let Some(depth_topic) = pick(&depths, &["depth"]).cloned() else {
            let mut found: Vec<String> = topics
                .iter()
                .map(|(t, i)| format!("{t} ({})", i.first.encoding))
                .collect();
            found.sort();
            return Err(RosbagError::NoDepthStream {
                image_topics: found,
            });
        };
        let depth_info =
            camera_info_of(&c, &depth_topic).ok_or_else(|| RosbagError::MissingCalibration {
                what: format!("the depth stream's camera_info (beside {depth_topic})"),
            })?;
        let depth = CameraModel::from_camera_info(depth_info, &depth_topic)?;
        if let Some(problem) = depth.intrinsics().problem() {
            return Err(RosbagError::MissingCalibration {
                what: format!("the depth stream's camera_info (beside {depth_topic}): {problem}"),
            });
        }
        let depth_images = c.images.get(&depth_topic).map(|i| &i.first);
        if let Some(first) = depth_images {
            check_size(&depth, first, &depth_topic)?;
        }
        let colour = colour_stream(&c, &depth_topic, &depth, &mut warnings)?;
        let depth_units_m = depth_units(&c, &depth_topic, &mut warnings)?;
        let depth_stamps = c
            .images
            .remove(&depth_topic)
            .map(|i| i.images)
            .unwrap_or_default();
        if depth_stamps.is_empty() {
            return Err(RosbagError::NoFrames { topic: depth_topic });
        }
        let colour_stamps = colour
            .as_ref()
            .and_then(|(t, _)| c.images.remove(t))
            .map(|i| i.images)
            .unwrap_or_default();
        let frames = pair(depth_stamps, &colour_stamps);
        let unpaired = frames.iter().filter(|f| f.colour.is_none()).count();
        if colour.is_some() && unpaired > 0 {
            warnings.push(RosbagError::FramesWithoutColour {
                unpaired,
                frames: frames.len(),
            });
        }
        let mut imu = std::mem::take(&mut c.imu);
        imu.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
        Ok(Self {
            depth_topic,
            depth,
            depth_units_m,
            colour,
            colour_images: colour_stamps.len(),
            frames,
            imu,
            warnings,
        })
    }
}

/// Refuses a stream whose images are not the size its camera info gives.
fn check_size(camera: &CameraModel, first: &ImageHead, topic: &str) -> Result<(), RosbagError> {
    if (first.width as usize, first.height as usize) != (camera.width, camera.height) {
        return Err(RosbagError::MissingCalibration {
            what: format!(
                "a camera_info of {topic}'s size: its images are {}x{}, its camera_info {}x{}",
                first.width, first.height, camera.width, camera.height
            ),
        });
    }
    Ok(())
}

/// The colour stream and its registration to depth; `None` (with a
/// warning) when it has no calibration. An encoding not read is an error.
fn colour_stream<L>(
    c: &Collected<L>,
    depth_topic: &str,
    depth: &CameraModel,
    warnings: &mut Vec<RosbagError>,
) -> Result<Option<(String, Registration)>, RosbagError> {
    let others: Vec<(&String, &ImageTopic<L>)> = c
        .images
        .iter()
        .filter(|(t, i)| t.as_str() != depth_topic && !is_depth_encoding(&i.first.encoding))
        .collect();
    let readable: Vec<_> = others
        .iter()
        .copied()
        .filter(|(_, i)| colour_bytes_per_pixel(&i.first.encoding).is_some())
        .collect();
    let colour_names = ["color", "colour", "rgb"];
    let Some(topic) = pick(&readable, &colour_names).cloned() else {
        let named = others.iter().find(|(t, _)| {
            let lower = t.to_ascii_lowercase();
            colour_names.iter().any(|n| lower.contains(n))
        });
        return match named {
            Some((t, i)) => Err(RosbagError::UnsupportedEncoding {
                topic: (*t).clone(),
                encoding: i.first.encoding.clone(),
                expected: "rgb8, bgr8, rgba8 or bgra8 colour",
            }),
            None => Ok(None),
        };
    };
    let no_colour = |reason: String| RosbagError::ColourWithoutCalibration {
        topic: topic.clone(),
        reason,
    };
    let Some(info) = camera_info_of(c, &topic) else {
        warnings.push(no_colour("it has no camera_info".to_owned()));
        return Ok(None);
    };
    let colour = CameraModel::from_camera_info(info, &topic)?;
    if let Some(problem) = colour.intrinsics().problem() {
        warnings.push(no_colour(format!("its camera_info: {problem}")));
        return Ok(None);
    }
    if let Some(first) = c.images.get(&topic).map(|i| &i.first) {
        check_size(&colour, first, &topic)?;
    }
    let depth_tf = extrinsics_of(c, depth_topic, None);
    let colour_tf = depth_tf.and_then(|(id, _)| extrinsics_of(c, &topic, Some(id)));
    let (Some((_, to_depth)), Some((_, to_colour))) = (depth_tf, colour_tf) else {
        warnings.push(no_colour(
            "the recording gives no extrinsics (tf/N) of both streams to one reference".to_owned(),
        ));
        return Ok(None);
    };
    Ok(Some((
        topic,
        Registration {
            depth: *depth,
            colour,
            colour_from_depth: to_colour * to_depth.inverse(),
        },
    )))
}

/// The depth units option under the depth stream's sensor (or any), or
/// the default with a warning; an implausible value is an error.
fn depth_units<L>(
    c: &Collected<L>,
    depth_topic: &str,
    warnings: &mut Vec<RosbagError>,
) -> Result<f64, RosbagError> {
    let sensor = parent(stream_of(depth_topic), 1);
    let mut found: Vec<(&String, &f32)> = c.depth_units.iter().collect();
    found.sort_by_key(|(t, _)| (!t.starts_with(sensor), t.as_str()));
    let Some((topic, &units)) = found.first() else {
        warnings.push(RosbagError::NoDepthUnits {
            assumed_m: DEFAULT_DEPTH_UNITS_M,
        });
        return Ok(DEFAULT_DEPTH_UNITS_M);
    };
    // The option is a float32 of a decimal setting (0.001, 0.0002): its
    // shortest decimal, so that 1 / units is the scale meant (1000, not
    // 999.99994).
    let units: f64 = units.to_string().parse().unwrap_or(f64::from(units));
    if !(units.is_finite() && units > 1e-7 && units <= 0.1) {
        return Err(RosbagError::Message {
            topic: (*topic).clone(),
            reason: format!("depth units of {units} m (expected 1e-7 to 0.1)"),
        });
    }
    Ok(units)
}

/// Depth images in time order, each with the colour image nearest in time
/// if within half the depth's median frame period (the colour's, with one
/// depth image; 1/30 s with one of each).
fn pair<L: Copy>(mut depth: Vec<(f64, L)>, colour: &[(f64, L)]) -> Vec<BagFrame<L>> {
    depth.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut colour: Vec<(f64, L)> = colour.to_vec();
    colour.sort_by(|a, b| a.0.total_cmp(&b.0));
    let period = median_step(&depth)
        .or_else(|| median_step(&colour))
        .unwrap_or(1.0 / 30.0);
    let half = 0.5 * period;
    depth
        .into_iter()
        .map(|(t, location)| {
            let i = colour.partition_point(|(tc, _)| *tc < t);
            let nearest = [i.checked_sub(1), Some(i)]
                .into_iter()
                .flatten()
                .filter_map(|j| colour.get(j))
                .min_by(|a, b| (a.0 - t).abs().total_cmp(&(b.0 - t).abs()))
                .filter(|(tc, _)| (tc - t).abs() <= half)
                .copied();
            BagFrame {
                time_s: t,
                depth: location,
                colour: nearest,
            }
        })
        .collect()
}

/// The median time between consecutive stamps, if positive.
fn median_step<L>(stamps: &[(f64, L)]) -> Option<f64> {
    let mut steps: Vec<f64> = stamps.windows(2).map(|w| w[1].0 - w[0].0).collect();
    steps.sort_by(f64::total_cmp);
    steps.get(steps.len() / 2).copied().filter(|s| *s > 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(t: f64) -> (f64, Location) {
        let location = Location {
            chunk_pos: (t * 1000.0) as u64,
            offset: 0,
            len: 0,
        };
        (t, location)
    }

    #[test]
    fn colour_pairs_with_the_nearest_depth_within_half_a_period() {
        // Depth at 30 Hz (half a period: 16.7 ms); colour at 0.010 (pairs
        // with 0.0; 23 ms from 0.0333), 0.070 (0.0667) and 0.118 (18 ms
        // from 0.1: too far).
        let depth: Vec<_> = [0.1, 0.0, 1.0 / 30.0, 2.0 / 30.0].map(at).to_vec();
        let colour = [0.010, 0.070, 0.118].map(at);
        let frames = pair(depth, &colour);
        let stamps: Vec<f64> = frames.iter().map(|f| f.time_s).collect();
        assert_eq!(stamps, vec![0.0, 1.0 / 30.0, 2.0 / 30.0, 0.1], "time order");
        let paired: Vec<Option<f64>> = frames.iter().map(|f| f.colour.map(|c| c.0)).collect();
        assert_eq!(paired, vec![Some(0.010), None, Some(0.070), None]);
    }

    #[test]
    fn topic_parents() {
        let t = "/device_0/sensor_0/Depth_0/image/data";
        assert_eq!(parent(t, 2), "/device_0/sensor_0/Depth_0");
        assert_eq!(parent(t, 3), "/device_0/sensor_0");
        assert_eq!(stream_of(t), "/device_0/sensor_0/Depth_0");
        assert_eq!(
            stream_of("/device_0/sensor_0/Depth_0/image/data/compressedDepth"),
            "/device_0/sensor_0/Depth_0"
        );
        assert_eq!(
            stream_of("/device_0/sensor_1/Color_0/image/data/compressed"),
            "/device_0/sensor_1/Color_0"
        );
        assert!(is_depth_units_topic(
            "/device_0/sensor_0/option/Depth Units/value"
        ));
        assert!(is_depth_units_topic(
            "/device_0/sensor_0/option/Depth_Units/value"
        ));
    }
}
