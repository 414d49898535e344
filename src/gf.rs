//! Gf's matrix routines that usd-core's results depend on, as Gf computes
//! them (not the textbook optimum): UsdSkel's dual-quaternion skinning and
//! `UsdGeomCamera`'s frustum both orthonormalise with Gf's iterative method
//! and read rotations by Open Inventor's quaternion rule, so painterly does
//! too wherever it must agree with them.

use glam::{DMat3, DQuat, DVec3};

/// Gf's `GetOrthonormalized` of a matrix (column form: its columns are the
/// rows Gf works on): the three vectors normalised, then up to 20 rounds of
/// averaging each with itself minus its projections on the other two,
/// renormalised, until they move less than 1e-6.
pub fn orthonormalized(m: DMat3) -> DMat3 {
    let mut t = [
        m.x_axis.normalize_or_zero(),
        m.y_axis.normalize_or_zero(),
        m.z_axis.normalize_or_zero(),
    ];
    // GfIsClose of two vectors: the length of their difference, squared.
    let close = |a: DVec3, b: DVec3| (a - b).length_squared() <= 1e-6 * 1e-6;
    if close(t[0], t[1]) || close(t[0], t[2]) || close(t[1], t[2]) {
        return DMat3::from_cols(t[0], t[1], t[2]);
    }
    for _ in 0..20 {
        let a = t;
        let mut c = t;
        for i in 0..3 {
            let mut b = t[i];
            for (j, aj) in a.iter().enumerate() {
                if j != i {
                    b -= aj.dot(b) * *aj;
                }
            }
            c[i] = ((t[i] + b) * 0.5).normalize_or_zero();
        }
        let error: f64 = (0..3).map(|i| (t[i] - c[i]).length_squared()).sum();
        if error < 1e-12 {
            break;
        }
        t = c;
    }
    DMat3::from_cols(t[0], t[1], t[2])
}

/// Gf's `ExtractRotationQuaternion` of a matrix in column form (its columns
/// are Gf's rows): Open Inventor's rule, from the largest diagonal entry.
/// UsdSkel's DQS normals apply it to the orthonormalised normal matrix, which
/// is improper for a mirroring joint; glam's `from_mat3` expects a rotation
/// and answers differently there. Not normalised, as in Gf.
pub fn rotation_quaternion(m: &DMat3) -> DQuat {
    let g = |i: usize, j: usize| m.col(i)[j];
    let i = if g(0, 0) > g(1, 1) {
        if g(0, 0) > g(2, 2) {
            0
        } else {
            2
        }
    } else if g(1, 1) > g(2, 2) {
        1
    } else {
        2
    };
    let trace = g(0, 0) + g(1, 1) + g(2, 2);
    let (real, im) = if trace > g(i, i) {
        let r = 0.5 * (trace + 1.0).sqrt();
        let im = DVec3::new(g(1, 2) - g(2, 1), g(2, 0) - g(0, 2), g(0, 1) - g(1, 0)) / (4.0 * r);
        (r, im)
    } else {
        let (j, k) = ((i + 1) % 3, (i + 2) % 3);
        let q = 0.5 * (g(i, i) - g(j, j) - g(k, k) + 1.0).sqrt();
        let mut im = DVec3::ZERO;
        im[i] = q;
        im[j] = (g(i, j) + g(j, i)) / (4.0 * q);
        im[k] = (g(k, i) + g(i, k)) / (4.0 * q);
        ((g(j, k) - g(k, j)) / (4.0 * q), im)
    };
    DQuat::from_xyzw(im.x, im.y, im.z, real.clamp(-1.0, 1.0))
}
