//! Azure Kinect calibration (`calibration.json`, attached to a
//! `k4arecorder` file): each camera's intrinsics for the recorded mode and
//! its extrinsics from the depth camera. The file gives intrinsics
//! normalised by the sensor's size (1024x1024 depth, 4096x3072 colour),
//! zero at the corner of the first pixel; a mode is a binned or cropped
//! part of the sensor, as the Azure Kinect SDK tabulates them
//! (`mode_specific_calibration.c`): scaled to its binned resolution,
//! shifted by its crop, then by half a pixel to pixel centres.

use glam::{DAffine3, DMat3, DVec3};

use super::MkvError;

/// One camera of the recording in its mode: pixels, metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AzureCamera {
    /// Focal length along x, pixels.
    pub fx: f64,
    /// Focal length along y, pixels.
    pub fy: f64,
    /// Principal point x, pixels (pixel centres at integers).
    pub cx: f64,
    /// Principal point y, pixels.
    pub cy: f64,
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// The rational Brown-Conrady coefficients `[k1, k2, k3, k4, k5, k6,
    /// codx, cody, p2, p1]` (normalised image coordinates), as the file
    /// gives them.
    pub distortion: [f64; 10],
    /// Largest radius (normalised image coordinates) the distortion holds for.
    pub metric_radius: f64,
    /// This camera from the depth camera (`p_camera = T * p_depth`), metres.
    pub from_depth: DAffine3,
}

impl AzureCamera {
    /// The pixel where the camera sees point `p` (its frame, metres), as
    /// the SDK projects (`transformation_project_internal`, Brown-Conrady):
    /// `None` behind the camera or past the metric radius.
    #[must_use]
    pub fn project(&self, p: DVec3) -> Option<(f64, f64)> {
        if p.z <= 0.0 {
            return None;
        }
        let [k1, k2, k3, k4, k5, k6, codx, cody, p2, p1] = self.distortion;
        let (xp, yp) = (p.x / p.z - codx, p.y / p.z - cody);
        let rs = xp * xp + yp * yp;
        if rs > self.metric_radius * self.metric_radius {
            return None;
        }
        let a = 1.0 + k1 * rs + k2 * rs * rs + k3 * rs * rs * rs;
        let b = 1.0 + k4 * rs + k5 * rs * rs + k6 * rs * rs * rs;
        let d = if b == 0.0 { a } else { a / b };
        let x = xp * d + (rs + 2.0 * xp * xp) * p2 + 2.0 * xp * yp * p1 + codx;
        let y = yp * d + (rs + 2.0 * yp * yp) * p1 + 2.0 * xp * yp * p2 + cody;
        Some((x * self.fx + self.cx, y * self.fy + self.cy))
    }
}

/// Which camera of the calibration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Purpose {
    /// The depth (and IR) camera.
    Depth,
    /// The colour camera.
    Colour,
}

/// A mode: the sensor binned to `binned`, cropped at `crop`, giving `output`.
struct Mode {
    binned: (f64, f64),
    crop: (f64, f64),
}

/// The depth modes by their image size (NFOV binned and unbinned, WFOV
/// binned and unbinned or passive IR).
fn depth_mode(width: usize, height: usize) -> Option<Mode> {
    let (binned, crop) = match (width, height) {
        (320, 288) => ((512.0, 512.0), (96.0, 90.0)),
        (640, 576) => ((1024.0, 1024.0), (192.0, 180.0)),
        (512, 512) => ((512.0, 512.0), (0.0, 0.0)),
        (1024, 1024) => ((1024.0, 1024.0), (0.0, 0.0)),
        _ => return None,
    };
    Some(Mode { binned, crop })
}

/// The colour modes by their image size (720p to 3072p; 16:9 modes are
/// cropped from the sensor's 4:3).
fn colour_mode(width: usize, height: usize) -> Option<Mode> {
    let (binned, crop) = match (width, height) {
        (1280, 720) => ((1280.0, 960.0), (0.0, 120.0)),
        (1920, 1080) => ((1920.0, 1440.0), (0.0, 180.0)),
        (2560, 1440) => ((2560.0, 1920.0), (0.0, 240.0)),
        (2048, 1536) => ((2048.0, 1536.0), (0.0, 0.0)),
        (3840, 2160) => ((3840.0, 2880.0), (0.0, 360.0)),
        (4096, 3072) => ((4096.0, 3072.0), (0.0, 0.0)),
        _ => return None,
    };
    Some(Mode { binned, crop })
}

fn bad(reason: String) -> MkvError {
    MkvError::Calibration(reason)
}

/// Numbers of a JSON array field.
fn numbers(value: &serde_json::Value, key: &str, n: usize) -> Result<Vec<f64>, MkvError> {
    let out: Vec<f64> = value
        .get(key)
        .and_then(serde_json::Value::as_array)
        .map(|a| a.iter().filter_map(serde_json::Value::as_f64).collect())
        .unwrap_or_default();
    if out.len() < n || out.iter().any(|v| !v.is_finite()) {
        return Err(bad(format!("`{key}` is not {n} finite numbers")));
    }
    Ok(out)
}

/// The camera `purpose` of a `calibration.json` (its bytes; a trailing NUL
/// is allowed) in the mode of a `width` x `height` image.
pub fn camera(
    json: &[u8],
    purpose: Purpose,
    width: usize,
    height: usize,
) -> Result<AzureCamera, MkvError> {
    let text = json
        .iter()
        .rposition(|&b| b == b'}')
        .and_then(|end| json.get(..=end))
        .ok_or_else(|| bad("not JSON".to_owned()))?;
    let root: serde_json::Value =
        serde_json::from_slice(text).map_err(|e| bad(format!("not JSON: {e}")))?;
    let wanted = match purpose {
        Purpose::Depth => "CALIBRATION_CameraPurposeDepth",
        Purpose::Colour => "CALIBRATION_CameraPurposePhotoVideo",
    };
    let cam = root
        .pointer("/CalibrationInformation/Cameras")
        .and_then(serde_json::Value::as_array)
        .and_then(|cams| {
            cams.iter()
                .find(|c| c.get("Purpose").and_then(serde_json::Value::as_str) == Some(wanted))
        })
        .ok_or_else(|| bad(format!("no camera of purpose {wanted}")))?;
    let intrinsics = cam
        .get("Intrinsics")
        .ok_or_else(|| bad(format!("{wanted}: no Intrinsics")))?;
    let p = numbers(intrinsics, "ModelParameters", 14)?;
    let sensor = (
        cam.get("SensorWidth").and_then(serde_json::Value::as_f64),
        cam.get("SensorHeight").and_then(serde_json::Value::as_f64),
    );
    let mode = match purpose {
        Purpose::Depth => {
            if sensor != (Some(1024.0), Some(1024.0)) {
                return Err(bad(format!("{wanted}: a sensor other than 1024x1024")));
            }
            depth_mode(width, height)
        }
        Purpose::Colour => {
            if sensor != (Some(4096.0), Some(3072.0)) {
                return Err(bad(format!(
                    "{wanted}: a sensor other than 4096x3072 (a legacy 16:9 calibration is not read)"
                )));
            }
            colour_mode(width, height)
        }
    }
    .ok_or_else(|| bad(format!("{wanted}: no recording mode of {width}x{height}")))?;
    let rt = cam
        .get("Rt")
        .ok_or_else(|| bad(format!("{wanted}: no Rt")))?;
    let r = numbers(rt, "Rotation", 9)?;
    let t = numbers(rt, "Translation", 3)?;
    // Row-major in the file.
    let rotation = DMat3::from_cols_array(&[r[0], r[3], r[6], r[1], r[4], r[7], r[2], r[5], r[8]]);
    let metric_radius = cam
        .get("MetricRadius")
        .and_then(serde_json::Value::as_f64)
        .filter(|r| r.is_finite() && *r > 0.0)
        .unwrap_or(f64::INFINITY);
    let mut distortion = [0.0; 10];
    distortion.copy_from_slice(&p[4..14]);
    Ok(AzureCamera {
        fx: p[2] * mode.binned.0,
        fy: p[3] * mode.binned.1,
        cx: p[0] * mode.binned.0 - mode.crop.0 - 0.5,
        cy: p[1] * mode.binned.1 - mode.crop.1 - 0.5,
        width,
        height,
        distortion,
        metric_radius,
        from_depth: DAffine3::from_mat3_translation(rotation, DVec3::new(t[0], t[1], t[2])),
    })
}
