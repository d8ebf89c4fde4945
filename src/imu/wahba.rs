//! Wahba's problem (the rotation that best maps one set of vectors onto
//! another, Wahba 1965), solved by the SVD of their cross-covariance
//! (Markley 1988), and how well a set of vectors pins a rotation.

use glam::{DMat3, DQuat, DVec3};
use nalgebra::Matrix3;

/// The rotation `R` minimising `sum |a - R b|^2` over `pairs` `(a, b)`;
/// `None` when the SVD does not converge or the result is not finite.
/// Degenerate sets (every vector along one line) give some rotation that
/// fits; [`weakest_axis`] says whether a set pins one.
pub(crate) fn wahba(pairs: impl Iterator<Item = (DVec3, DVec3)>) -> Option<DQuat> {
    let mut h = Matrix3::<f64>::zeros();
    for (a, b) in pairs {
        for r in 0..3 {
            for c in 0..3 {
                h[(r, c)] += b[r] * a[c];
            }
        }
    }
    let svd = h.try_svd(true, true, 1e-12, 200)?;
    let (u, v_t) = (svd.u?, svd.v_t?);
    let v = v_t.transpose();
    let mut d = Matrix3::<f64>::identity();
    // A reflection is never a mounting: flip the weakest axis.
    if (v * u.transpose()).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let r: DMat3 = crate::se3::dmat3_from_nalgebra(&(v * d * u.transpose()));
    let q = DQuat::from_mat3(&r).normalize();
    q.is_finite().then_some(q)
}

/// The information a set of vectors carries about a small rotation of
/// them: `sum |b|^2 I - b b^T` (the Gauss-Newton matrix of
/// `sum |a - R b|^2` about `R`, up to a factor 2). Its smallest eigenvalue
/// and that eigenvector: the axis about which turning the vectors changes
/// the fit least (zero for vectors all along one line: turning about that
/// line moves none of them). `None` when the eigen-solver fails.
pub(crate) fn weakest_axis(vectors: impl Iterator<Item = DVec3>) -> Option<(f64, DVec3)> {
    let mut m = Matrix3::<f64>::zeros();
    for b in vectors {
        let n2 = b.length_squared();
        for r in 0..3 {
            for c in 0..3 {
                let identity = if r == c { n2 } else { 0.0 };
                m[(r, c)] += identity - b[r] * b[c];
            }
        }
    }
    let eigen = m.try_symmetric_eigen(1e-12, 200)?;
    let (i, &value) = eigen
        .eigenvalues
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))?;
    let axis = eigen.eigenvectors.column(i);
    Some((value.max(0.0), DVec3::new(axis[0], axis[1], axis[2])))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::portable_math::quat_from_axis_angle;

    #[test]
    fn recovers_a_rotation_and_finds_the_free_axis() {
        let truth = quat_from_axis_angle(DVec3::new(0.2, -0.9, 0.4).normalize(), 2.4);
        let bs = [
            DVec3::new(1.0, 0.2, -0.3),
            DVec3::new(-0.1, 0.8, 0.5),
            DVec3::new(0.3, -0.4, 0.9),
            DVec3::new(-0.6, 0.1, 0.2),
        ];
        let q = wahba(bs.iter().map(|&b| (truth * b, b))).unwrap();
        let error = crate::imu::rotation_vector(q.inverse() * truth).length();
        assert!(error < 1e-9, "{error}");
        let (value, _) = weakest_axis(bs.iter().copied()).unwrap();
        assert!(value > 0.1);
        let line = DVec3::new(0.0, 0.6, 0.8);
        let (value, axis) = weakest_axis([line, -2.0 * line, 0.5 * line].into_iter()).unwrap();
        assert!(value < 1e-12 && axis.cross(line).length() < 1e-9);
    }
}
