//! A 6x6 Cholesky factorisation on plain arrays. nalgebra's generic `Cholesky` is correct but
//! its loops are written for any size and took a third of a 4-point solve; this one is unrolled
//! by the compiler for the one size the solver needs.

use nalgebra::{Matrix6, Vector6};

/// Lower-triangular factor `L` with `A = L L^T`, or `None` when `A` is not (numerically)
/// positive definite.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Chol6 {
    l: [[f64; 6]; 6],
}

impl Chol6 {
    /// Factorises the symmetric matrix `a` (only its lower triangle is read).
    #[inline]
    pub(crate) fn new(a: &Matrix6<f64>) -> Option<Self> {
        let mut l = [[0.0f64; 6]; 6];
        for j in 0..6 {
            let d = a[(j, j)] - l[j][..j].iter().map(|v| v * v).sum::<f64>();
            if d.is_nan() || d <= 0.0 {
                return None;
            }
            let djj = d.sqrt();
            l[j][j] = djj;
            let inv = 1.0 / djj;
            for i in j + 1..6 {
                let s = a[(i, j)]
                    - l[i][..j]
                        .iter()
                        .zip(&l[j][..j])
                        .map(|(x, y)| x * y)
                        .sum::<f64>();
                l[i][j] = s * inv;
            }
        }
        Some(Self { l })
    }

    /// Solves `A x = b`.
    #[inline]
    pub(crate) fn solve(&self, b: &Vector6<f64>) -> Vector6<f64> {
        let l = &self.l;
        let mut y = [0.0f64; 6];
        for i in 0..6 {
            let mut s = b[i];
            for k in 0..i {
                s -= l[i][k] * y[k];
            }
            y[i] = s / l[i][i];
        }
        let mut x = Vector6::zeros();
        for i in (0..6).rev() {
            let mut s = y[i];
            for k in i + 1..6 {
                s -= l[k][i] * x[k];
            }
            x[i] = s / l[i][i];
        }
        x
    }

    /// `A^-1`.
    pub(crate) fn inverse(&self) -> Matrix6<f64> {
        let mut inv = Matrix6::zeros();
        for c in 0..6 {
            let mut e = Vector6::zeros();
            e[c] = 1.0;
            inv.set_column(c, &self.solve(&e));
        }
        // Exact symmetry.
        (inv + inv.transpose()) * 0.5
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_nalgebra() {
        let m = Matrix6::from_fn(|i, j| {
            ((i * 7 + j * 3) % 5) as f64 - 2.0 + if i == j { 3.0 } else { 0.0 }
        });
        let a = m * m.transpose() + Matrix6::identity();
        let b = Vector6::new(1.0, -2.0, 0.5, 3.0, 0.0, -1.0);
        let x = Chol6::new(&a).expect("positive definite").solve(&b);
        assert!((a * x - b).amax() < 1e-10);
        let inv = Chol6::new(&a).expect("positive definite").inverse();
        assert!((a * inv - Matrix6::identity()).amax() < 1e-10);
        assert!(Chol6::new(&Matrix6::zeros()).is_none());
        let mut nan = a;
        nan[(2, 2)] = f64::NAN;
        assert!(Chol6::new(&nan).is_none());
    }
}
