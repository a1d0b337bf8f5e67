//! The triangular factor of a sensitivity matrix, built one row at a time.
//!
//! Everything the orthogonal ranking (Alg. 5.1) needs from `Z` (n × p) is its Gram matrix
//! `ZᵀZ`, and `ZᵀZ = RᵀR` for the upper-triangular `R` of a QR factorisation. Rows are folded
//! into `R` by Givens rotations — O(p²) per row, O(p²) memory whatever n, and no `ZᵀZ` is ever
//! formed (which would square the condition number). The same factor serves the on-line
//! version: exponential forgetting scales `R` by `√λ` before a row; a sliding window removes
//! the oldest row by a hyperbolic (downdating) rotation in the "mixed" form of LINPACK's
//! `dchdd`, which is the stable variant.

use nalgebra::DMatrix;

/// Upper-triangular `R` with `RᵀR = Σ λ^(n−i) z_i z_iᵀ` over the rows folded in.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct TriangularFactor {
    p: usize,
    /// Row-major upper triangle (the lower part stays zero).
    r: Vec<f64>,
    /// Scratch row, so that [`add_row`](Self::add_row) leaves the caller's row alone.
    work: Vec<f64>,
    /// Copy of `r` taken before a downdate, restored if it fails.
    backup: Vec<f64>,
    rows: u64,
}

/// Removing a row would leave a factor that is not positive definite: the row was never added,
/// or rounding has eaten the information (the window is nearly rank-deficient).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DowndateError {
    /// The pivot at which `r_kk² − z_k²` was not positive.
    pub column: usize,
}

impl TriangularFactor {
    /// An empty factor for rows of length `p`.
    pub fn new(p: usize) -> Self {
        Self {
            p,
            r: vec![0.0; p * p],
            work: vec![0.0; p],
            backup: vec![0.0; p * p],
            rows: 0,
        }
    }

    /// Number of columns p.
    pub fn p(&self) -> usize {
        self.p
    }

    /// Rows folded in (minus rows removed).
    pub fn rows(&self) -> u64 {
        self.rows
    }

    /// Forget everything.
    pub fn clear(&mut self) {
        self.r.fill(0.0);
        self.rows = 0;
    }

    /// Fold in one row `z` (length p): `RᵀR ← RᵀR + z zᵀ`. Allocation-free.
    ///
    /// # Panics
    /// If `z.len() != p` (the caller's invariant).
    pub fn add_row(&mut self, z: &[f64]) {
        assert_eq!(z.len(), self.p, "row length");
        let p = self.p;
        let w = &mut self.work;
        w.copy_from_slice(z);
        for k in 0..p {
            let b = w[k];
            if b == 0.0 {
                continue;
            }
            let row = &mut self.r[k * p..(k + 1) * p];
            let a = row[k];
            // √(a² + b²): `hypot` would guard against overflow beyond ~1e154 at twice the cost
            // of the whole sweep; users of the factor check that it is finite.
            let h = (a * a + b * b).sqrt();
            let (c, s) = (a / h, b / h);
            row[k] = h;
            for (rkj, wj) in row[k + 1..].iter_mut().zip(&mut w[k + 1..]) {
                let (x, y) = (*rkj, *wj);
                *rkj = c * x + s * y;
                *wj = c * y - s * x;
            }
        }
        self.rows += 1;
    }

    /// Remove a row previously added: `RᵀR ← RᵀR − z zᵀ` (sliding window). On failure the
    /// factor is unchanged. Allocation-free.
    ///
    /// # Panics
    /// If `z.len() != p`.
    pub fn remove_row(&mut self, z: &[f64]) -> Result<(), DowndateError> {
        assert_eq!(z.len(), self.p, "row length");
        let p = self.p;
        // Whether a pivot fails is known only once the rotations before it are applied: keep
        // a copy to restore.
        self.backup.copy_from_slice(&self.r);
        let w = &mut self.work;
        w.copy_from_slice(z);
        for k in 0..p {
            let row = &mut self.r[k * p..(k + 1) * p];
            let (a, b) = (row[k], w[k]);
            if b == 0.0 {
                continue;
            }
            let d = (a - b) * (a + b);
            if !(d > 0.0 && a > 0.0) {
                self.r.copy_from_slice(&self.backup);
                return Err(DowndateError { column: k });
            }
            let h = d.sqrt();
            let (c, s) = (h / a, b / a);
            row[k] = h;
            for (rkj, wj) in row[k + 1..].iter_mut().zip(&mut w[k + 1..]) {
                let r_new = (*rkj - s * *wj) / c;
                *wj = c * *wj - s * r_new;
                *rkj = r_new;
            }
        }
        self.rows = self.rows.saturating_sub(1);
        Ok(())
    }

    /// Multiply the factor by `f` (`RᵀR ← f²·RᵀR`): exponential forgetting with `f = √λ`.
    pub fn scale(&mut self, f: f64) {
        for v in &mut self.r {
            *v *= f;
        }
    }

    /// `R` as a matrix (p × p, upper triangular).
    pub fn r(&self) -> DMatrix<f64> {
        DMatrix::from_row_slice(self.p, self.p, &self.r)
    }

    /// `R` into `m` (p × p), allocating nothing.
    pub fn r_into(&self, m: &mut DMatrix<f64>) {
        for i in 0..self.p {
            for j in 0..self.p {
                m[(i, j)] = self.r[i * self.p + j];
            }
        }
    }

    /// Whether every entry is finite (false after an overflow or a non-finite row).
    pub fn is_finite(&self) -> bool {
        self.r.iter().all(|v| v.is_finite())
    }

    /// Entry `R[i, j]`.
    pub fn get(&self, i: usize, j: usize) -> f64 {
        self.r[i * self.p + j]
    }

    /// The Gram matrix `RᵀR` (= `ZᵀZ`).
    pub fn gram(&self) -> DMatrix<f64> {
        let r = self.r();
        r.transpose() * r
    }
}
