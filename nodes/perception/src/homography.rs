//! The perspective transform of the calibration, computed with the same double-precision
//! arithmetic as OpenCV's `getPerspectiveTransform` (an 8x8 system solved by Gaussian elimination
//! with partial pivoting) and the inverse with the same 3x3 cofactor formula as its `invert`, so
//! that the warp lookup table reproduces `warpPerspective` bit for bit.

/// A 3x3 homography, row-major.
pub(crate) type Matrix3 = [f64; 9];

/// The homography that maps the four `source` points onto the four `destination` points.
/// Points are given as `f32`, as OpenCV's API takes them.
pub(crate) fn perspective_transform(source: &[[f32; 2]; 4], destination: &[[f32; 2]; 4]) -> Option<Matrix3> {
    let mut a = [[0.0f64; 8]; 8];
    let mut b = [0.0f64; 8];
    for i in 0..4 {
        let (sx, sy) = (source[i][0] as f64, source[i][1] as f64);
        let (dx, dy) = (destination[i][0] as f64, destination[i][1] as f64);
        a[i] = [sx, sy, 1.0, 0.0, 0.0, 0.0, -sx * dx, -sy * dx];
        a[i + 4] = [0.0, 0.0, 0.0, sx, sy, 1.0, -sx * dy, -sy * dy];
        b[i] = dx;
        b[i + 4] = dy;
    }
    let x = solve_lu(a, b)?;
    Some([x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7], 1.0])
}

/// Solves `a x = b` by Gaussian elimination with partial pivoting and back substitution.
#[expect(clippy::needless_range_loop, reason = "OpenCV's elimination, index for index, for the same bits")]
fn solve_lu<const N: usize>(mut a: [[f64; N]; N], mut b: [f64; N]) -> Option<[f64; N]> {
    let epsilon = f64::EPSILON * 100.0;
    for i in 0..N {
        let mut pivot = i;
        for j in i + 1..N {
            if a[j][i].abs() > a[pivot][i].abs() {
                pivot = j;
            }
        }
        if a[pivot][i].abs() < epsilon {
            return None;
        }
        if pivot != i {
            for j in i..N {
                let t = a[i][j];
                a[i][j] = a[pivot][j];
                a[pivot][j] = t;
            }
            b.swap(i, pivot);
        }
        let d = -1.0 / a[i][i];
        for j in i + 1..N {
            let alpha = a[j][i] * d;
            for k in i + 1..N {
                a[j][k] += alpha * a[i][k];
            }
            b[j] += alpha * b[i];
        }
    }
    for i in (0..N).rev() {
        let mut s = b[i];
        for k in i + 1..N {
            s -= a[i][k] * b[k];
        }
        b[i] = s / a[i][i];
    }
    Some(b)
}

/// The inverse of a 3x3 matrix by cofactors, or `None` when it is singular.
pub(crate) fn invert(m: &Matrix3) -> Option<Matrix3> {
    let at = |r: usize, c: usize| m[r * 3 + c];
    let det = at(0, 0) * (at(1, 1) * at(2, 2) - at(1, 2) * at(2, 1))
        - at(0, 1) * (at(1, 0) * at(2, 2) - at(1, 2) * at(2, 0))
        + at(0, 2) * (at(1, 0) * at(2, 1) - at(1, 1) * at(2, 0));
    if det == 0.0 {
        return None;
    }
    let d = 1.0 / det;
    Some([
        (at(1, 1) * at(2, 2) - at(1, 2) * at(2, 1)) * d,
        (at(0, 2) * at(2, 1) - at(0, 1) * at(2, 2)) * d,
        (at(0, 1) * at(1, 2) - at(0, 2) * at(1, 1)) * d,
        (at(1, 2) * at(2, 0) - at(1, 0) * at(2, 2)) * d,
        (at(0, 0) * at(2, 2) - at(0, 2) * at(2, 0)) * d,
        (at(0, 2) * at(1, 0) - at(0, 0) * at(1, 2)) * d,
        (at(1, 0) * at(2, 1) - at(1, 1) * at(2, 0)) * d,
        (at(0, 1) * at(2, 0) - at(0, 0) * at(2, 1)) * d,
        (at(0, 0) * at(1, 1) - at(0, 1) * at(1, 0)) * d,
    ])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Applies a homography to a point.
    fn apply(m: &Matrix3, x: f64, y: f64) -> (f64, f64) {
        let w = m[6] * x + m[7] * y + m[8];
        ((m[0] * x + m[1] * y + m[2]) / w, (m[3] * x + m[4] * y + m[5]) / w)
    }

    const SOURCE: [[f32; 2]; 4] = [[14.0, 140.0], [301.0, 140.0], [200.0, 96.0], [118.0, 96.0]];
    const DESTINATION: [[f32; 2]; 4] = [[155.0, 154.0], [165.0, 154.0], [165.0, 144.0], [155.0, 144.0]];

    #[test]
    fn maps_the_calibration_points_and_inverts() {
        let m = perspective_transform(&SOURCE, &DESTINATION).unwrap();
        for (s, d) in SOURCE.iter().zip(&DESTINATION) {
            let (x, y) = apply(&m, s[0] as f64, s[1] as f64);
            assert!((x - d[0] as f64).abs() < 1e-9 && (y - d[1] as f64).abs() < 1e-9, "({x}, {y}) vs {d:?}");
        }
        let inverse = invert(&m).unwrap();
        let (x, y) = apply(&inverse, 160.0, 150.0);
        let (bx, by) = apply(&m, x, y);
        assert!((bx - 160.0).abs() < 1e-9 && (by - 150.0).abs() < 1e-9);
    }

    #[test]
    fn degenerate_points_have_no_transform() {
        let collinear = [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0]];
        assert!(perspective_transform(&collinear, &DESTINATION).is_none());
    }
}
