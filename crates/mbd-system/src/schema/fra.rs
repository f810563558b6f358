//! The US Federal Railroad Administration (FRA) track classes 1-6 as displacement spectra
//! (`psd: {fra: {class, irregularity}}` of a generated profile).
//!
//! **Forms.** One-sided spectra in the spatial angular frequency `Omega` (rad/m), in
//! cm^2/(rad/m), with the class's roughness constants `A_v` (vertical profile) and `A_a`
//! (alignment) in cm^2 rad/m, its break frequencies `Omega_c` and `Omega_s` (rad/m) and
//! `k = 0.25`:
//! ```text
//! vertical profile  S_v(Omega) = k A_v Omega_c^2 / (Omega^2 (Omega^2 + Omega_c^2))
//! alignment         S_a(Omega) = k A_a Omega_c^2 / (Omega^2 (Omega^2 + Omega_c^2))
//! cross-level       S_c(Omega) = 4 k A_v Omega_c^2 / ((Omega^2 + Omega_c^2)(Omega^2 + Omega_s^2))
//! ```
//! Each is `N / ((Omega^2 + P^2)(Omega^2 + Q^2))` with `(P, Q) = (0, Omega_c)` for the profile
//! and the alignment, `(Omega_c, Omega_s)` for the cross-level.
//!
//! **Table.** [`FRA_CLASSES`]: the FRA class constants as tabulated in W. Zhai, *Vehicle-Track
//! Coupled Dynamics: Theory and Applications* (Springer, 2020), the chapter on track
//! irregularities (US track spectra), after V. K. Garg and R. V. Dukkipati, *Dynamics of
//! Railway Vehicle Systems* (Academic Press, 1984). Class 6 is the best track, class 1 the
//! worst. Cross-check: class 5's `A_v` and the shape of the vertical form agree with the
//! defaults of the public ROSE railway model (github.com/PlatypusBytes/ROSE: 2.095e-5 m^2 rad/m,
//! `Omega_c` = 0.8242 rad/m there).
//!
//! **Conversion** to the generator's unit (spatial frequency `f` in cycles/m, `S` in
//! mm^2/(1/m)): `Omega = 2 pi f`, and a band's power is the same in both variables,
//! `S(f) df = S(Omega) dOmega`, so `S(f) = 2 pi S(Omega = 2 pi f)`; cm^2 = 100 mm^2. With
//! `Omega^2 + P^2 = (2 pi)^2 (f^2 + p^2)`, `p = P / (2 pi)`:
//! ```text
//! S(f) = 100 (2 pi) N / ((2 pi)^4 (f^2 + p^2)(f^2 + q^2)) = c / ((f^2 + p^2)(f^2 + q^2)),
//! c = 100 N / (2 pi)^3   (mm^2 (1/m)^3),   p = P / (2 pi),  q = Q / (2 pi)   (1/m)
//! ```

use super::RawPsd;
use std::f64::consts::TAU;

/// The factor `k` of the FRA forms.
pub const FRA_K: f64 = 0.25;

/// One FRA track class's constants.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FraClass {
    /// Vertical profile roughness `A_v` (cm^2 rad/m).
    pub a_v: f64,
    /// Alignment roughness `A_a` (cm^2 rad/m).
    pub a_a: f64,
    /// Break frequency `Omega_s` of the cross-level (rad/m).
    pub omega_s: f64,
    /// Break frequency `Omega_c` (rad/m).
    pub omega_c: f64,
}

/// FRA classes 1 to 6 (`FRA_CLASSES[class - 1]`); the source is in the module documentation.
pub const FRA_CLASSES: [FraClass; 6] = [
    FraClass {
        a_v: 1.2107,
        a_a: 3.3634,
        omega_s: 0.6046,
        omega_c: 0.8245,
    },
    FraClass {
        a_v: 1.0181,
        a_a: 1.2107,
        omega_s: 0.9308,
        omega_c: 0.8245,
    },
    FraClass {
        a_v: 0.6816,
        a_a: 0.4128,
        omega_s: 0.8520,
        omega_c: 0.8245,
    },
    FraClass {
        a_v: 0.5376,
        a_a: 0.3027,
        omega_s: 1.1312,
        omega_c: 0.8245,
    },
    FraClass {
        a_v: 0.2095,
        a_a: 0.0762,
        omega_s: 0.8209,
        omega_c: 0.8245,
    },
    FraClass {
        a_v: 0.0339,
        a_a: 0.0339,
        omega_s: 0.4380,
        omega_c: 0.8245,
    },
];

/// Which of a class's spectra (`irregularity:` of `psd: {fra: ...}`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FraIrregularity {
    /// Vertical profile (`A_v`).
    Vertical,
    /// Alignment, lateral (`A_a`).
    Alignment,
    /// Cross-level (`A_v`, `Omega_s`).
    CrossLevel,
}

impl FraIrregularity {
    /// Every irregularity with its keyword, in the order a message lists them.
    pub const ALL: [(FraIrregularity, &'static str); 3] = [
        (FraIrregularity::Vertical, "vertical"),
        (FraIrregularity::Alignment, "alignment"),
        (FraIrregularity::CrossLevel, "cross_level"),
    ];

    /// The irregularity of a keyword.
    pub fn from_keyword(keyword: &str) -> Option<Self> {
        Self::ALL
            .iter()
            .find(|(_, k)| *k == keyword)
            .map(|(i, _)| *i)
    }
}

/// The spectrum of FRA class `class` (1 to 6) for `irregularity` in the generator's unit
/// ([`RawPsd::TwoPole`], conversion in the module documentation); `None` for another class.
pub fn fra_psd(class: usize, irregularity: FraIrregularity) -> Option<RawPsd> {
    let t = FRA_CLASSES.get(class.checked_sub(1)?)?;
    // N (cm^2 (rad/m)^3) and the poles P, Q (rad/m) of S(Omega) = N / ((Omega^2 + P^2)(Omega^2 + Q^2)).
    let (n, p, q) = match irregularity {
        FraIrregularity::Vertical => (FRA_K * t.a_v * t.omega_c.powi(2), 0.0, t.omega_c),
        FraIrregularity::Alignment => (FRA_K * t.a_a * t.omega_c.powi(2), 0.0, t.omega_c),
        FraIrregularity::CrossLevel => (
            4.0 * FRA_K * t.a_v * t.omega_c.powi(2),
            t.omega_c,
            t.omega_s,
        ),
    };
    Some(RawPsd::TwoPole {
        c: 100.0 * n / TAU.powi(3),
        p: p / TAU,
        q: q / TAU,
    })
}
