//! A hand held in front of the camera: a patch that moves with it, for
//! the mask of things carried with the camera
//! ([`crate::preprocess::camera_fixed`]).

use crate::frame::RgbdFrame;

/// Puts a hand in `frame`: a tilted patch covering the image's lower-right
/// `share` of its width and height (`share` 0.3: 9 % of the image),
/// `depth_m` away at its near corner and 10 cm deeper across, skin
/// coloured with a little shading; its left edge wobbles by up to 2 pixels
/// with `frame_index`, as a hand does.
pub fn hold_hand_in_view(frame: &mut RgbdFrame, share: f64, depth_m: f64, frame_index: usize) {
    let (w, h) = (frame.width, frame.height);
    let wobble = (libm::sin(frame_index as f64 * 0.7) * 2.0) as isize;
    let x0 = ((1.0 - share) * w as f64) as isize + wobble;
    let y0 = ((1.0 - share) * h as f64) as isize;
    for y in 0..h {
        for x in 0..w {
            let (xi, yi) = (x as isize, y as isize);
            if xi < x0 || yi < y0 {
                continue;
            }
            let u = (xi - x0) as f64 / (w as f64 * share);
            let v = (yi - y0) as f64 / (h as f64 * share);
            let p = y * w + x;
            if let Some(z) = frame.depth_m.get_mut(p) {
                *z = (depth_m + 0.1 * u + 0.03 * v) as f32;
            }
            let shade = 0.8 + 0.2 * libm::sin(u * 9.0) * libm::cos(v * 7.0);
            if let Some(rgb) = frame.rgb.get_mut(3 * p..3 * p + 3) {
                rgb.copy_from_slice(&[
                    (220.0 * shade) as u8,
                    (170.0 * shade) as u8,
                    (140.0 * shade) as u8,
                ]);
            }
        }
    }
}
