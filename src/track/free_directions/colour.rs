//! Which held directions the photometric term pins: colour on a view
//! whose geometry leaves directions free (a textured ceiling or wall).

use super::FreeDirections;
use crate::se3::NormalEquations;

impl FreeDirections {
    /// Splits the held directions by what the photometric term `colour`
    /// (normal equations in grey/255 units) says about them: the motions
    /// within the held span whose standard deviation under colour, from
    /// its information `U A U^T / s^2` (`s^2` its mean squared weighted
    /// residual, one residual an independent measurement) is below
    /// `max_sigma` (metres; radians at 1 m) are pinned by colour, the
    /// others stay held. Returns (pinned by colour, still held); all
    /// still held when `colour` has fewer than `min_residuals` residuals.
    #[must_use]
    pub fn split_by_colour(
        &self,
        colour: &NormalEquations,
        max_sigma: f64,
        min_residuals: usize,
    ) -> (Self, Self) {
        let mut basis = *self;
        basis.orthonormalise();
        let k = basis.count;
        let variance = colour.cost / colour.count.max(1) as f64;
        if k == 0
            || colour.count < min_residuals
            || !(variance > 0.0 && variance.is_finite())
            || max_sigma.is_nan()
            || max_sigma <= 0.0
        {
            return (Self::default(), *self);
        }
        let a = colour.full_matrix();
        let u = &basis.directions;
        let restricted = nalgebra::DMatrix::<f64>::from_fn(k, k, |i, j| {
            let mut sum = 0.0;
            for r in 0..6 {
                for c in 0..6 {
                    sum += u[i][r] * a[r][c] * u[j][c];
                }
            }
            sum / variance
        });
        if !restricted.iter().all(|v| v.is_finite()) {
            return (Self::default(), *self);
        }
        let eigen = nalgebra::SymmetricEigen::new(restricted);
        let needed = 1.0 / (max_sigma * max_sigma);
        let (mut pinned, mut held) = (Self::default(), Self::default());
        for (i, &information) in eigen.eigenvalues.iter().enumerate() {
            let e = eigen.eigenvectors.column(i);
            let v: [f64; 6] = std::array::from_fn(|r| (0..k).map(|j| e[j] * u[j][r]).sum());
            let side = if information >= needed {
                &mut pinned
            } else {
                &mut held
            };
            side.directions[side.count] = v;
            side.count += 1;
        }
        held.smallest_eigenvalue = self.smallest_eigenvalue;
        (pinned, held)
    }
}
