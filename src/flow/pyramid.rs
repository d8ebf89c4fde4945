//! Grey-level image pyramid with central-difference gradients, reused buffers.

use glam::Vec2;

/// One level: grey levels and their gradients, row-major.
#[derive(Debug, Default, Clone)]
pub struct GreyLevel {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Per pixel `[grey, d/du, d/dv]` (gradients zero on the border).
    pub pixels: Vec<[f32; 3]>,
}

impl GreyLevel {
    /// Bilinear sample of `[grey, d/du, d/dv]` at `p` (level pixels), or `None`
    /// when the 2x2 neighbourhood leaves the image.
    #[inline]
    pub fn sample(&self, p: Vec2) -> Option<[f32; 3]> {
        if !(p.x >= 0.0 && p.y >= 0.0) {
            return None;
        }
        let (u0, v0) = (p.x.floor(), p.y.floor());
        let (u, v) = (u0 as usize, v0 as usize);
        if u + 1 >= self.width || v + 1 >= self.height {
            return None;
        }
        let (fu, fv) = (p.x - u0, p.y - v0);
        let i = v * self.width + u;
        let (a, b) = (self.pixels[i], self.pixels[i + 1]);
        let (c, d) = (self.pixels[i + self.width], self.pixels[i + self.width + 1]);
        let mut out = [0.0; 3];
        for ch in 0..3 {
            let top = a[ch] + fu * (b[ch] - a[ch]);
            let bottom = c[ch] + fu * (d[ch] - c[ch]);
            out[ch] = top + fv * (bottom - top);
        }
        Some(out)
    }
}

/// Levels finest first; level `l` is `2^l` times smaller (2x2 means).
#[derive(Debug, Default, Clone)]
pub struct GreyPyramid {
    levels: Vec<GreyLevel>,
}

impl GreyPyramid {
    /// Level `l` (the caller built at least `l + 1` levels).
    #[must_use]
    pub fn level(&self, l: usize) -> &GreyLevel {
        &self.levels[l.min(self.levels.len().saturating_sub(1))]
    }

    /// Number of levels built.
    #[must_use]
    pub fn len(&self) -> usize {
        self.levels.len()
    }

    /// Fills `levels` levels from `grey` (`width * height`, checked by the caller).
    pub fn build(&mut self, grey: &[f32], width: usize, height: usize, levels: usize) {
        self.levels.resize_with(levels, GreyLevel::default);
        for l in 0..levels {
            let (done, rest) = self.levels.split_at_mut(l);
            let level = &mut rest[0];
            if l == 0 {
                level.width = width;
                level.height = height;
                level.pixels.resize(width * height, [0.0; 3]);
                for (px, &g) in level.pixels.iter_mut().zip(grey) {
                    *px = [g, 0.0, 0.0];
                }
            } else {
                let fine = &done[l - 1];
                let (w, h) = (fine.width / 2, fine.height / 2);
                level.width = w;
                level.height = h;
                level.pixels.resize(w * h, [0.0; 3]);
                for v in 0..h {
                    for u in 0..w {
                        let i = 2 * v * fine.width + 2 * u;
                        let sum = fine.pixels[i][0]
                            + fine.pixels[i + 1][0]
                            + fine.pixels[i + fine.width][0]
                            + fine.pixels[i + fine.width + 1][0];
                        level.pixels[v * w + u] = [0.25 * sum, 0.0, 0.0];
                    }
                }
            }
            gradients(level);
        }
    }
}

fn gradients(level: &mut GreyLevel) {
    let (w, h) = (level.width, level.height);
    if w < 3 || h < 3 {
        return;
    }
    for v in 1..h - 1 {
        for u in 1..w - 1 {
            let i = v * w + u;
            let gx = 0.5 * (level.pixels[i + 1][0] - level.pixels[i - 1][0]);
            let gy = 0.5 * (level.pixels[i + w][0] - level.pixels[i - w][0]);
            level.pixels[i][1] = gx;
            level.pixels[i][2] = gy;
        }
    }
}
