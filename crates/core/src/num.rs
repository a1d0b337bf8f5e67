//! A number as a person reads it in a message ([`Num`]): Rust's `{}` writes an `f64` without an
//! exponent, so a flag given `1e300` came back as 301 digits in the error that refused it.

use std::fmt;

/// `x` as Rust writes it (shortest round-trip form) when `10⁻⁴ ≤ |x| < 10¹⁵` or `x` is 0 or not
/// finite, in exponent form beyond (`1e300`, `-1.5e-9`): every digit of the value, never a
/// screenful of zeros.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Num(pub f64);

impl fmt::Display for Num {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let a = self.0.abs();
        if self.0 == 0.0 || !self.0.is_finite() || (1e-4..1e15).contains(&a) {
            write!(f, "{}", self.0)
        } else {
            write!(f, "{:e}", self.0)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Num;

    #[test]
    fn short_in_every_range() {
        for (x, want) in [
            (0.0, "0"),
            (1000.0, "1000"),
            (0.95, "0.95"),
            (1e-4, "0.0001"),
            (123456789012345.0, "123456789012345"),
            (1e15, "1e15"),
            (1e300, "1e300"),
            (-1.7976931348623157e308, "-1.7976931348623157e308"),
            (5e-324, "5e-324"),
            (-2.5e-9, "-2.5e-9"),
            (f64::INFINITY, "inf"),
            (f64::NAN, "NaN"),
        ] {
            assert_eq!(Num(x).to_string(), want);
        }
    }
}
