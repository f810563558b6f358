//! A minimal complex number (`re + i im`) for the frequency responses of the reference
//! problems: sums, products, quotients, modulus and argument, nothing else.

use std::ops::{Add, Div, Mul, Neg, Sub};

/// `re + i im`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct C64 {
    /// Real part.
    pub re: f64,
    /// Imaginary part.
    pub im: f64,
}

impl C64 {
    /// `re + i im`.
    pub const fn new(re: f64, im: f64) -> Self {
        Self { re, im }
    }

    /// A real number.
    pub const fn real(re: f64) -> Self {
        Self { re, im: 0.0 }
    }

    /// `|z|`.
    pub fn abs(self) -> f64 {
        self.re.hypot(self.im)
    }

    /// `|z|^2`.
    pub fn norm_sqr(self) -> f64 {
        self.re * self.re + self.im * self.im
    }

    /// `arg z` in `(-pi, pi]`.
    pub fn arg(self) -> f64 {
        self.im.atan2(self.re)
    }

    /// `conj z`.
    pub fn conj(self) -> Self {
        Self::new(self.re, -self.im)
    }

    /// `a z` for real `a`.
    pub fn scale(self, a: f64) -> Self {
        Self::new(a * self.re, a * self.im)
    }
}

impl Add for C64 {
    type Output = C64;
    fn add(self, o: C64) -> C64 {
        C64::new(self.re + o.re, self.im + o.im)
    }
}

impl Sub for C64 {
    type Output = C64;
    fn sub(self, o: C64) -> C64 {
        C64::new(self.re - o.re, self.im - o.im)
    }
}

impl Neg for C64 {
    type Output = C64;
    fn neg(self) -> C64 {
        C64::new(-self.re, -self.im)
    }
}

impl Mul for C64 {
    type Output = C64;
    fn mul(self, o: C64) -> C64 {
        C64::new(
            self.re * o.re - self.im * o.im,
            self.re * o.im + self.im * o.re,
        )
    }
}

impl Div for C64 {
    type Output = C64;
    fn div(self, o: C64) -> C64 {
        let d = o.norm_sqr();
        C64::new(
            (self.re * o.re + self.im * o.im) / d,
            (self.im * o.re - self.re * o.im) / d,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn field_operations_invert_each_other() {
        let (a, b) = (C64::new(1.5, -2.0), C64::new(-0.25, 3.0));
        let q = (a * b) / b;
        assert!((q - a).abs() < 1e-15);
        assert_eq!((a + b) - b, a);
        assert!((C64::new(0.0, 1.0) * C64::new(0.0, 1.0) - C64::real(-1.0)).abs() == 0.0);
        assert!((C64::new(3.0, 4.0).abs() - 5.0).abs() < 1e-15);
        assert!((C64::new(0.0, 2.0).arg() - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
    }
}
