//! The 14 per-sample parameters of the spec (`docs/model.md`, Parameters).
//!
//! Masses and inertias are for the **whole vehicle** (the one-rail model halves them, see
//! [`crate::vehicle::Vehicle`]); suspension stiffness and damping are per axle box (primary)
//! and per bogie side (secondary); `v_kmh` is in km/h, everything else SI.

use serde::{Deserialize, Serialize};

/// Number of per-sample parameters.
pub const NUM_PARAMETERS: usize = 14;

/// Parameter names in the spec's table order (identical to `pino_data::schema::PARAMETERS`).
pub const PARAMETER_NAMES: [&str; NUM_PARAMETERS] = [
    "m_c", "j_c", "m_t", "j_t", "m_w", "k_p", "c_p", "k_s", "c_s", "l_c", "l_t", "v_kmh", "k_f",
    "c_f",
];

/// One sample's parameters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SampleParams {
    /// Car-body mass, whole vehicle (kg). Nominal 38880.
    pub m_c: f64,
    /// Car-body pitch inertia, whole vehicle (kg m^2). Nominal 1.91e6.
    pub j_c: f64,
    /// Bogie frame mass, whole (kg). Nominal 3060.
    pub m_t: f64,
    /// Bogie pitch inertia, whole (kg m^2). Nominal 3200.
    pub j_t: f64,
    /// Wheelset mass, whole (kg). Nominal 1517.
    pub m_w: f64,
    /// Primary vertical stiffness per axle box (N/m). Nominal 1.772e6.
    pub k_p: f64,
    /// Primary vertical damping per axle box (N s/m). Nominal 2e4.
    pub c_p: f64,
    /// Secondary vertical stiffness per bogie side (N/m). Nominal 4.5e5.
    pub k_s: f64,
    /// Secondary vertical damping per bogie side (N s/m). Nominal 2e4.
    pub c_s: f64,
    /// Half distance between bogie centres (m). Nominal 9.
    pub l_c: f64,
    /// Half wheelbase (m). Nominal 1.2.
    pub l_t: f64,
    /// Running speed (km/h). Range 300-350.
    pub v_kmh: f64,
    /// Fastener (rail pad) vertical stiffness (N/m). Range 3.5e7-4.5e7.
    pub k_f: f64,
    /// Fastener vertical damping (N s/m). Range 4e4-5e4.
    pub c_f: f64,
}

impl SampleParams {
    /// The CRH380 nominal vehicle with mid-range speed and fastener values.
    pub const NOMINAL: SampleParams = SampleParams {
        m_c: 38880.0,
        j_c: 1.91e6,
        m_t: 3060.0,
        j_t: 3200.0,
        m_w: 1517.0,
        k_p: 1.772e6,
        c_p: 2e4,
        k_s: 4.5e5,
        c_s: 2e4,
        l_c: 9.0,
        l_t: 1.2,
        v_kmh: 325.0,
        k_f: 4.0e7,
        c_f: 4.5e4,
    };

    /// Values in [`PARAMETER_NAMES`] order.
    pub fn to_array(&self) -> [f64; NUM_PARAMETERS] {
        [
            self.m_c, self.j_c, self.m_t, self.j_t, self.m_w, self.k_p, self.c_p, self.k_s,
            self.c_s, self.l_c, self.l_t, self.v_kmh, self.k_f, self.c_f,
        ]
    }

    /// From values in [`PARAMETER_NAMES`] order.
    pub fn from_array(a: [f64; NUM_PARAMETERS]) -> Self {
        Self {
            m_c: a[0],
            j_c: a[1],
            m_t: a[2],
            j_t: a[3],
            m_w: a[4],
            k_p: a[5],
            c_p: a[6],
            k_s: a[7],
            c_s: a[8],
            l_c: a[9],
            l_t: a[10],
            v_kmh: a[11],
            k_f: a[12],
            c_f: a[13],
        }
    }

    /// Running speed in m/s.
    pub fn speed(&self) -> f64 {
        self.v_kmh / 3.6
    }

    /// Checks that every value is finite and strictly positive (a negative mass or
    /// stiffness is not a vehicle).
    pub fn validate(&self) -> crate::Result<()> {
        for (name, value) in PARAMETER_NAMES.iter().zip(self.to_array()) {
            if !(value.is_finite() && value > 0.0) {
                return Err(crate::Error::OutOfRange {
                    name: (*name).to_owned(),
                    value,
                    allowed: "finite and > 0".to_owned(),
                });
            }
        }
        Ok(())
    }
}
