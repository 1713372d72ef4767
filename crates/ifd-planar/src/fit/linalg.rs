//! The dense linear algebra of the refits, on nalgebra: the Cholesky factor
//! of a support's Gram matrix (with a tiny ridge when near-coincident atoms
//! make it singular), its solves, and the inverses whose diagonals score
//! atoms for removal. Slices are row-major; the Gram matrix and its
//! inverse are symmetric, so the layout only matters for the factor.

use nalgebra::{DMatrix, DVector, Dyn, linalg::Cholesky};

/// The Cholesky factorisation `G = L L^T` of a support's Gram matrix.
pub(super) struct Factor {
    chol: Cholesky<f64, Dyn>,
    s: usize,
}

/// The Cholesky factor of `gram` (`s x s`), with a tiny ridge added when
/// needed (unit-norm atoms: `diag(G) = 1`; near-coincident atoms make `G`
/// singular).
pub(super) fn factor(gram: &[f64], s: usize) -> Factor {
    let g = DMatrix::from_row_slice(s, s, gram);
    let mut ridge = 1e-12;
    let mut m = g.clone();
    loop {
        if let Some(chol) = m.clone().cholesky()
            && chol
                .l_dirty()
                .diagonal()
                .iter()
                .all(|d| d.is_finite() && *d > 0.0)
        {
            return Factor { chol, s };
        }
        m = &g + DMatrix::identity(s, s) * ridge;
        ridge *= 100.0;
    }
}

impl Factor {
    /// Solves `G x = rhs` in place.
    pub(super) fn solve(&self, x: &mut [f64]) {
        let mut v = DVector::from_column_slice(x);
        self.chol.solve_mut(&mut v);
        x.copy_from_slice(v.as_slice());
    }

    /// `L^-1`, lower triangular.
    fn lower_inverse(&self) -> DMatrix<f64> {
        let l = self.chol.l();
        let mut inv = DMatrix::identity(self.s, self.s);
        // L is non-singular: its diagonal is positive (checked in `factor`).
        let solved = l.solve_lower_triangular_mut(&mut inv);
        debug_assert!(solved);
        inv
    }

    /// `diag(G^-1)` = column sums of squares of `L^-1`.
    pub(super) fn inverse_diagonal(&self) -> Vec<f64> {
        let inv = self.lower_inverse();
        inv.column_iter().map(|c| c.norm_squared()).collect()
    }

    /// `G^-1 = L^-T L^-1`, row-major (symmetric).
    pub(super) fn full_inverse(&self) -> Vec<f64> {
        let inv = self.lower_inverse();
        let h = inv.tr_mul(&inv);
        // symmetric: the column-major slice is the row-major one
        h.as_slice().to_vec()
    }
}
