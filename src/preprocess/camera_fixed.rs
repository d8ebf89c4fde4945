//! Things that move with the camera: a hand holding the sensor at the
//! image's edge, a finger over the lens, a cable, the robot's own arm.
//!
//! Such a thing is near, and it stays at the same pixels with the same
//! depth and colour while the rest of the image changes as the camera
//! moves. Tracked as part of the scene, it anchors the camera: it fits
//! "no motion" exactly, and along directions the scene pins poorly it
//! wins (the synthetic room with a patch of 9 % of the image at 0.35 m:
//! every frame tracked, each slid 1.2-1.5 cm, 30.8 cm ATE against 0.28 cm
//! without the patch; `examples/swings.rs --hand`).
//!
//! [`CameraFixedMask`] samples the input frame on a grid of cells (one
//! pixel a cell, about 160 cells across) and counts, per cell, the frames
//! in a row in which the cell stayed (depth within `max(1 cm, 2 %)`, grey
//! within [`GREY_TOL`]) while at least half of the cells with depth in
//! both frames changed, or half of the far ones (beyond [`NEAR_M`], when
//! they are [`MIN_FAR_SHARE`] of the grid): the camera moved. The far
//! cells alone, so that a hand over much of the view does not hide the
//! motion of the rest (a patch of 16 % of the image: 9.9 cm ATE with all
//! cells only, 0.91 cm so). A near cell ([`NEAR_M`]) that
//! stayed through `min_frames` such frames, and its neighbours, lose their
//! depth before preprocessing: neither tracked nor fused. A frame where
//! few cells change (a camera at rest, the slow motion of every shared
//! sequence) leaves the counts as they are, and a cell that changes starts
//! again from 0, so a static scene is never masked.

use crate::frame::RgbdFrame;

/// Cells across the frame's width, about: the grid's step is
/// `ceil(width / CELLS_ACROSS)` pixels.
pub const CELLS_ACROSS: usize = 160;
/// Depth change that counts as staying, relative (2 %) ...
pub const DEPTH_TOL_RELATIVE: f32 = 0.02;
/// ... and at least this, metres.
pub const DEPTH_TOL_M: f32 = 0.01;
/// Grey change (0-255, the mean of R, G and B) that counts as staying.
pub const GREY_TOL: i32 = 10;
/// Share of the cells with depth in both frames, or of the far ones
/// (beyond [`NEAR_M`]) alone, that must change for the camera to count as
/// moving.
pub const MOVING_SHARE: f32 = 0.5;
/// The far cells count alone when they are at least this share of the
/// grid (a scan of a desk within reach has few).
pub const MIN_FAR_SHARE: f32 = 0.1;
/// Only cells nearer than this are masked, metres: what the camera
/// carries is within reach of the hand holding it.
pub const NEAR_M: f32 = 1.0;

/// Neighbouring cells whose depths differ by at most this share of the
/// nearer belong to one surface.
pub const CONTINUOUS: f32 = 0.05;
/// Share of a still part's outline within the image that must step back
/// to a farther surface (or to no depth) for it to be masked.
pub const SEPARATED_SHARE: f32 = 0.5;

/// Smallest part masked: one cell in this many of the grid (0.5 %, a
/// 40x40-pixel patch of a 640x480 frame). Smaller still parts on the
/// shared sequences are bits of surfaces cut out by missing depth.
pub const MIN_PART_SHARE_INV: usize = 200;

/// Per-cell memory of the last frame and of how long each cell stayed.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CameraFixedMask {
    /// Grid step, pixels (0 before the first frame).
    step: usize,
    /// Cells across and down.
    cols: usize,
    rows: usize,
    /// Last frame's depth (metres, 0 = none) and grey at each cell.
    depth_m: Vec<f32>,
    grey: Vec<u8>,
    /// Moving frames in a row each cell stayed through.
    still: Vec<u8>,
    /// Cells masked in the frame last observed.
    masked: Vec<bool>,
    /// How many of them.
    masked_count: usize,
    /// Per-frame buffers, reused.
    scratch: Scratch,
}

/// Buffers one frame's decision fills, kept between frames so that a
/// frame allocates nothing; not part of the state.
#[derive(Debug, Clone, Default, PartialEq)]
struct Scratch {
    /// Cells whose depth or grey changed since the last frame.
    changed: Vec<bool>,
    /// The part each cell was flood-filled into (its seed), or `usize::MAX`.
    part: Vec<usize>,
    /// Cells of a part that is masked.
    fixed: Vec<bool>,
    stack: Vec<usize>,
    members: Vec<usize>,
}

impl CameraFixedMask {
    /// Takes in `frame` (input resolution): updates each cell's count
    /// against the last frame observed and decides which cells are masked
    /// in this one. Returns how many cells are masked.
    pub fn observe(&mut self, frame: &RgbdFrame, min_frames: u8) -> usize {
        let step = frame.width.div_ceil(CELLS_ACROSS).max(1);
        let (cols, rows) = (frame.width.div_ceil(step), frame.height.div_ceil(step));
        if (step, cols, rows) != (self.step, self.cols, self.rows) {
            let n = cols * rows;
            *self = Self::with(step, cols, rows, vec![0.0; n], vec![0; n], vec![0; n]);
        }
        let sample = |c: usize| {
            let (x, y) = ((c % cols) * step, (c / cols) * step);
            let p = y * frame.width + x;
            let z = frame.depth_m.get(p).copied().unwrap_or(0.0);
            let rgb = frame.rgb.get(3 * p..3 * p + 3).unwrap_or(&[0, 0, 0]);
            let grey = (u16::from(rgb[0]) + u16::from(rgb[1]) + u16::from(rgb[2])) / 3;
            (if z.is_finite() && z > 0.0 { z } else { 0.0 }, grey as u8)
        };
        let mut changed = std::mem::take(&mut self.scratch.changed);
        changed.clear();
        changed.resize(cols * rows, false);
        // Cells with depth in both frames, and of those the changed: all of
        // them, and the far ones alone.
        let (mut both, mut moved) = (0usize, 0usize);
        let (mut both_far, mut moved_far) = (0usize, 0usize);
        for (c, change) in changed.iter_mut().enumerate() {
            let (z, g) = sample(c);
            let (pz, pg) = (self.depth_m[c], self.grey[c]);
            if z > 0.0 && pz > 0.0 {
                let tol = (DEPTH_TOL_RELATIVE * z).max(DEPTH_TOL_M);
                *change = (z - pz).abs() > tol || (i32::from(g) - i32::from(pg)).abs() > GREY_TOL;
                both += 1;
                moved += usize::from(*change);
                if z >= NEAR_M && pz >= NEAR_M {
                    both_far += 1;
                    moved_far += usize::from(*change);
                }
            }
            self.depth_m[c] = z;
            self.grey[c] = g;
        }
        let most_changed =
            |both: usize, moved: usize| both > 0 && moved as f32 >= MOVING_SHARE * both as f32;
        let enough_far = both_far as f32 >= MIN_FAR_SHARE * (cols * rows) as f32;
        let moving = most_changed(both, moved) || (enough_far && most_changed(both_far, moved_far));
        for (c, &change) in changed.iter().enumerate() {
            if change {
                self.still[c] = 0;
            } else if moving && self.depth_m[c] > 0.0 {
                self.still[c] = self.still[c].saturating_add(1);
            }
        }
        self.scratch.changed = changed;
        let count = self.mask_separated_still_parts(min_frames);
        self.masked_count = count;
        count
    }

    /// Marks the connected parts of near cells that stayed `min_frames`
    /// moving frames (neighbours within [`CONTINUOUS`] of each other's
    /// depth) whose outline within the image is mostly a step back to a
    /// farther surface or to no depth ([`SEPARATED_SHARE`]), and the cells next
    /// to them. A stretch of bare wall or floor that stayed (a camera
    /// sliding along it) is bounded by more of itself, not by a step:
    /// it is left alone. Returns how many cells are masked.
    fn mask_separated_still_parts(&mut self, min_frames: u8) -> usize {
        let (cols, rows) = (self.cols, self.rows);
        let n = cols * rows;
        let candidate = |c: usize| {
            min_frames > 0
                && self.still[c] >= min_frames
                && self.depth_m[c] > 0.0
                && self.depth_m[c] < NEAR_M
        };
        let neighbours = |c: usize| {
            let (x, y) = (c % cols, c / cols);
            [
                (x > 0).then(|| c - 1),
                (x + 1 < cols).then(|| c + 1),
                (y > 0).then(|| c - cols),
                (y + 1 < rows).then(|| c + cols),
            ]
        };
        let mut part = std::mem::take(&mut self.scratch.part);
        let mut fixed = std::mem::take(&mut self.scratch.fixed);
        let mut stack = std::mem::take(&mut self.scratch.stack);
        let mut members = std::mem::take(&mut self.scratch.members);
        part.clear();
        part.resize(n, usize::MAX);
        fixed.clear();
        fixed.resize(n, false);
        for seed in 0..n {
            if part[seed] != usize::MAX || !candidate(seed) {
                continue;
            }
            part[seed] = seed;
            stack.push(seed);
            members.clear();
            let (mut outline, mut separated) = (0usize, 0usize);
            while let Some(c) = stack.pop() {
                members.push(c);
                let z = self.depth_m[c];
                for m in neighbours(c) {
                    // The image's edge says nothing either way.
                    let Some(m) = m else { continue };
                    let zm = self.depth_m[m];
                    let continuous = zm > 0.0 && (zm - z).abs() <= CONTINUOUS * z;
                    if continuous && candidate(m) {
                        if part[m] == usize::MAX {
                            part[m] = seed;
                            stack.push(m);
                        }
                    } else if part[m] != seed {
                        outline += 1;
                        // A rim masked last frame that is no candidate
                        // now but steps back right behind: the noisy edge
                        // of a part already masked, which must not come
                        // and go with it.
                        let stepped = |a: usize, za: f32| {
                            za <= 0.0 || {
                                neighbours(a).into_iter().flatten().any(|b| {
                                    let zb = self.depth_m[b];
                                    zb <= 0.0 || zb > za * (1.0 + CONTINUOUS)
                                })
                            }
                        };
                        separated += usize::from(
                            zm <= 0.0
                                || zm > z * (1.0 + CONTINUOUS)
                                || (continuous && self.masked[m] && stepped(m, zm)),
                        );
                    }
                }
            }
            let large = members.len() * MIN_PART_SHARE_INV >= n;
            if large && outline > 0 && separated as f32 >= SEPARATED_SHARE * outline as f32 {
                for &c in &members {
                    fixed[c] = true;
                }
            }
        }
        let mut count = 0;
        for c in 0..n {
            let (x, y) = (c % cols, c / cols);
            // The cells next to a fixed part hold its outline.
            let by_fixed = (y.saturating_sub(1)..(y + 2).min(rows))
                .any(|ny| (x.saturating_sub(1)..(x + 2).min(cols)).any(|nx| fixed[ny * cols + nx]));
            self.masked[c] = by_fixed && self.depth_m[c] > 0.0 && self.depth_m[c] < NEAR_M;
            count += usize::from(self.masked[c]);
        }
        self.scratch.part = part;
        self.scratch.fixed = fixed;
        self.scratch.stack = stack;
        self.scratch.members = members;
        count
    }

    /// Cells masked in the frame last observed.
    #[must_use]
    pub fn masked_count(&self) -> usize {
        self.masked_count
    }

    /// Decides the mask again from the counts, as [`Self::observe`] did
    /// at the last frame (for a state rebuilt by [`Self::from_parts`]).
    pub fn decide_mask_again(&mut self, min_frames: u8) {
        self.masked_count = self.mask_separated_still_parts(min_frames);
    }

    /// Which cells the last frame masked (row-major, the grid's cells).
    #[must_use]
    pub fn masked_cells(&self) -> &[bool] {
        &self.masked
    }

    /// Restores which cells the last frame masked (a session's; ignored
    /// unless one per cell).
    pub fn set_masked(&mut self, masked: Vec<bool>) {
        if masked.len() == self.masked.len() {
            self.masked_count = masked.iter().filter(|&&m| m).count();
            self.masked = masked;
        }
    }

    /// The most moving frames in a row a masked cell stayed through: how
    /// long what it masks has anchored the camera (0 when nothing is masked).
    #[must_use]
    pub fn longest_masked_still(&self) -> u8 {
        self.masked
            .iter()
            .zip(&self.still)
            .filter(|(&m, _)| m)
            .map(|(_, &s)| s)
            .max()
            .unwrap_or(0)
    }

    /// Whether a point seen at input pixel `(u, v)`, `z` metres in front
    /// of the camera, lies on what the last frame masked: a masked cell at
    /// or next to its pixel was measured within `max(1 cm, 2 %)` of `z`
    /// there (a surfel the masked thing left in the map, seen from the pose
    /// it anchored).
    #[must_use]
    pub fn covers(&self, u: f32, v: f32, z: f32) -> bool {
        if self.masked_count == 0 || self.step == 0 || !(z > 0.0 && u >= 0.0 && v >= 0.0) {
            return false;
        }
        // Truncation is floor for these non-negative values.
        let (x, y) = (u as usize / self.step, v as usize / self.step);
        if x >= self.cols || y >= self.rows {
            return false;
        }
        let tol = (DEPTH_TOL_RELATIVE * z).max(DEPTH_TOL_M);
        (y.saturating_sub(1)..(y + 2).min(self.rows)).any(|cy| {
            (x.saturating_sub(1)..(x + 2).min(self.cols)).any(|cx| {
                let c = cy * self.cols + cx;
                self.masked[c] && (self.depth_m[c] - z).abs() <= tol
            })
        })
    }

    /// Copies `frame` into `out` with the depth of every masked cell's
    /// pixels set to 0 (no measurement). Returns the share (0-1) of the
    /// frame's pixels that had depth and lost it.
    pub fn apply_into(&self, frame: &RgbdFrame, out: &mut RgbdFrame) -> f64 {
        out.width = frame.width;
        out.height = frame.height;
        out.rgb.clone_from(&frame.rgb);
        out.depth_m.clone_from(&frame.depth_m);
        out.depth_deviation.clone_from(&frame.depth_deviation);
        let mut taken = 0usize;
        for (c, _) in self.masked.iter().enumerate().filter(|(_, &m)| m) {
            let (x0, y0) = ((c % self.cols) * self.step, (c / self.cols) * self.step);
            for y in y0..(y0 + self.step).min(frame.height) {
                let row = y * frame.width;
                let (a, b) = (row + x0, row + (x0 + self.step).min(frame.width));
                if let Some(span) = out.depth_m.get_mut(a..b) {
                    taken += span.iter().filter(|&&z| z > 0.0).count();
                    span.fill(0.0);
                }
            }
        }
        taken as f64 / frame.depth_m.len().max(1) as f64
    }

    /// The state a session keeps: grid step, cells across and down, and per
    /// cell depth (metres), grey and count.
    #[must_use]
    pub fn parts(&self) -> (usize, usize, usize, &[f32], &[u8], &[u8]) {
        (
            self.step,
            self.cols,
            self.rows,
            &self.depth_m,
            &self.grey,
            &self.still,
        )
    }

    /// Rebuilds the state [`Self::parts`] gave; `None` when the parts do
    /// not fit together. The mask itself is recomputed by the next frame.
    #[must_use]
    pub fn from_parts(
        step: usize,
        cols: usize,
        rows: usize,
        depth_m: Vec<f32>,
        grey: Vec<u8>,
        still: Vec<u8>,
    ) -> Option<Self> {
        let n = cols.checked_mul(rows)?;
        let fits = depth_m.len() == n
            && grey.len() == n
            && still.len() == n
            && depth_m.iter().all(|z| z.is_finite() && *z >= 0.0);
        fits.then(|| Self::with(step, cols, rows, depth_m, grey, still))
    }

    /// A state with the given memory, nothing masked.
    fn with(
        step: usize,
        cols: usize,
        rows: usize,
        depth_m: Vec<f32>,
        grey: Vec<u8>,
        still: Vec<u8>,
    ) -> Self {
        Self {
            step,
            cols,
            rows,
            masked: vec![false; depth_m.len()],
            depth_m,
            grey,
            still,
            masked_count: 0,
            scratch: Scratch::default(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const W: usize = 160;
    const H: usize = 120;

    /// A wall 2 m away seen by a camera that moves: its depth and grey
    /// follow `t` (a ramp shifting across the image).
    fn moving_wall(t: usize) -> RgbdFrame {
        let mut f = RgbdFrame {
            width: W,
            height: H,
            rgb: vec![0; 3 * W * H],
            depth_deviation: Vec::new(),
            depth_m: vec![0.0; W * H],
        };
        for y in 0..H {
            for x in 0..W {
                let p = y * W + x;
                let phase = (x + 7 * t) % 40;
                f.depth_m[p] = 2.0 + 0.01 * phase as f32;
                f.rgb[3 * p..3 * p + 3].fill((6 * phase) as u8);
            }
        }
        f
    }

    /// `f` with a patch 0.4 m away over `x0..`, `y0..` (the lower right).
    fn with_patch(mut f: RgbdFrame, x0: usize, y0: usize, depth_m: f32) -> RgbdFrame {
        for y in y0..H {
            for x in x0..W {
                f.depth_m[y * W + x] = depth_m;
                f.rgb[3 * (y * W + x)..3 * (y * W + x) + 3].fill(200);
            }
        }
        f
    }

    fn masked_pixels(mask: &CameraFixedMask, f: &RgbdFrame) -> usize {
        let mut out = RgbdFrame::default();
        mask.apply_into(f, &mut out);
        out.depth_m.iter().filter(|&&z| z == 0.0).count()
    }

    #[test]
    fn a_patch_carried_with_a_moving_camera_is_masked_after_min_frames() {
        let mut mask = CameraFixedMask::default();
        let patch = 48 * 36;
        for t in 0..10 {
            let f = with_patch(moving_wall(t), W - 48, H - 36, 0.4);
            let cells = mask.observe(&f, 6);
            // Frame 0 has nothing to compare with; frames 1-5 count.
            if t < 6 {
                assert_eq!(cells, 0, "frame {t}");
            } else {
                let pixels = masked_pixels(&mask, &f);
                assert!(
                    pixels >= patch && pixels <= patch + 2 * (48 + 36) + 1,
                    "frame {t}: {pixels} pixels masked for a patch of {patch}"
                );
                // The wall keeps its depth.
                let mut out = RgbdFrame::default();
                mask.apply_into(&f, &mut out);
                assert!(out.depth_m[..W * (H - 40)].iter().all(|&z| z > 0.0));
            }
        }
    }

    #[test]
    fn a_hand_over_most_of_the_view_is_masked_too() {
        // 56 % of the image: the wall's cells, all changing, are fewer than
        // half of all cells.
        let (x0, y0) = (40, 30);
        let mut mask = CameraFixedMask::default();
        let mut masked = 0;
        for t in 0..10 {
            let f = with_patch(moving_wall(t), x0, y0, 0.4);
            mask.observe(&f, 6);
            masked = masked_pixels(&mask, &f);
        }
        let patch = (W - x0) * (H - y0);
        assert!(
            masked >= patch && masked <= patch + 2 * (W + H),
            "{masked} pixels masked for a patch of {patch}"
        );
    }

    #[test]
    fn nothing_is_masked_while_the_camera_rests_or_when_off() {
        let mut mask = CameraFixedMask::default();
        let still = with_patch(moving_wall(0), W - 48, H - 36, 0.4);
        for t in 0..20 {
            assert_eq!(mask.observe(&still, 6), 0, "frame {t}");
        }
        let mut off = CameraFixedMask::default();
        for t in 0..20 {
            let f = with_patch(moving_wall(t), W - 48, H - 36, 0.4);
            assert_eq!(off.observe(&f, 0), 0, "frame {t}");
        }
    }

    #[test]
    fn a_still_stretch_of_a_surface_that_goes_on_is_not_masked() {
        // The lower right stays at 0.4 m, as a bare floor does under a
        // camera sliding along it, but it goes on at the same depth into
        // the part that changes: no step back outlines it.
        let mut mask = CameraFixedMask::default();
        for t in 0..12 {
            let mut f = with_patch(moving_wall(t), W - 48, H - 36, 0.4);
            for y in 0..H {
                for x in 0..W {
                    if x < W - 48 || y < H - 36 {
                        f.depth_m[y * W + x] = 0.4 + 0.001 * ((x + 7 * t) % 5) as f32;
                    }
                }
            }
            assert_eq!(mask.observe(&f, 6), 0, "frame {t}");
        }
    }

    #[test]
    fn the_state_survives_its_parts_and_refuses_parts_that_do_not_fit() {
        let mut mask = CameraFixedMask::default();
        for t in 0..4 {
            mask.observe(&with_patch(moving_wall(t), W - 48, H - 36, 0.4), 6);
        }
        let (step, cols, rows, z, g, s) = mask.parts();
        let copy =
            CameraFixedMask::from_parts(step, cols, rows, z.to_vec(), g.to_vec(), s.to_vec());
        let mut copy = copy.expect("fits");
        for t in 4..10 {
            let f = with_patch(moving_wall(t), W - 48, H - 36, 0.4);
            assert_eq!(mask.observe(&f, 6), copy.observe(&f, 6), "frame {t}");
        }
        assert!(
            CameraFixedMask::from_parts(1, 2, 2, vec![0.0; 3], vec![0; 4], vec![0; 4]).is_none()
        );
        assert!(CameraFixedMask::from_parts(1, 1, 1, vec![f32::NAN], vec![0], vec![0]).is_none());
    }
}
