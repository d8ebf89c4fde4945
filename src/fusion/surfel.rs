//! One surfel's values, as fusion merges a measurement into it: position,
//! normal, colour, radius and confidence (world frame, metres).

use crate::portable_math::at_most;
use glam::Vec3;

/// One surfel's values, or one measurement about to be merged or added.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Surfel {
    /// Centre, world frame, metres.
    pub position: Vec3,
    /// Unit normal, world frame.
    pub normal: Vec3,
    /// RGBA8 colour (A = 255).
    pub colour: [u8; 4],
    /// Disk radius, metres.
    pub radius: f32,
    /// Confidence (for a measurement: its weight).
    pub confidence: f32,
}

impl Surfel {
    /// Confidence-weighted average of `self` and `other` (Keller et al.
    /// 2013): position, normal (renormalised) and colour averaged, the
    /// radius never grows, the confidences add up.
    #[inline]
    #[must_use]
    pub fn merged_with(&self, other: &Surfel) -> Surfel {
        let total = self.confidence + other.confidence;
        let (a, b) = (self.confidence / total, other.confidence / total);
        let normal = (self.normal * a + other.normal * b)
            .try_normalize()
            .unwrap_or(self.normal);
        // +0.5 then truncation rounds the non-negative mean without a libm call.
        let colour = std::array::from_fn(|c| {
            (f32::from(self.colour[c]) * a + f32::from(other.colour[c]) * b + 0.5) as u8
        });
        Surfel {
            position: self.position * a + other.position * b,
            normal,
            colour,
            radius: at_most(self.radius, self.radius * a + other.radius * b),
            confidence: total,
        }
    }
}
