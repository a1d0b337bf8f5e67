//! How many parameters to estimate: the mean-squared-error criterion of Wu, McLean, Harris and
//! McAuley (2011), "Selection of optimal parameter set using estimability analysis and MSE-based
//! model-selection criterion", Int. J. Advanced Mechatronic Systems 3(3).
//!
//! With `J_K` the weighted least-squares objective (residual sum of squares over the noise
//! variance) after estimating the K top-ranked parameters, the rest held at their nominal values:
//!
//! ```text
//! r_C,K   = (J_K − J_p)/(p − K)
//! r_CKub  = max(r_C,K − 1, 2·r_C,K/(p − K + 2))
//! r_CC,K  = (p − K)/N · (r_CKub − 1)              (K < p;  r_CC,p = 0)
//! K*      = argmin_K r_CC,K
//! ```

use serde::Serialize;

/// The criterion for K = 1 … p.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WuCriterion {
    /// `r_C,K`.
    pub r_c: Vec<f64>,
    /// `r_CKub` (the bias-corrected upper estimate).
    pub r_ckub: Vec<f64>,
    /// `r_CC,K`.
    pub r_cc: Vec<f64>,
    /// The number of parameters to estimate, `argmin r_CC,K` (lowest K on ties).
    pub k_star: usize,
}

/// The criterion from `j[K−1] = J_K` (K = 1 … p) and N data points. `None` if `j` is empty.
pub fn wu_criterion(j: &[f64], n: usize) -> Option<WuCriterion> {
    let p = j.len();
    let jp = *j.last()?;
    let (mut r_c, mut r_ckub, mut r_cc) = (Vec::new(), Vec::new(), Vec::new());
    for (k0, &jk) in j.iter().enumerate() {
        let k = k0 + 1;
        if k == p {
            r_c.push(0.0);
            r_ckub.push(0.0);
            r_cc.push(0.0);
            break;
        }
        let pk = (p - k) as f64;
        let rc = (jk - jp) / pk;
        let ub = (rc - 1.0).max(2.0 * rc / (pk + 2.0));
        r_c.push(rc);
        r_ckub.push(ub);
        r_cc.push(pk / n as f64 * (ub - 1.0));
    }
    let mut k_star = 1;
    for (k0, &v) in r_cc.iter().enumerate() {
        if v < r_cc[k_star - 1] {
            k_star = k0 + 1;
        }
    }
    Some(WuCriterion {
        r_c,
        r_ckub,
        r_cc,
        k_star,
    })
}
