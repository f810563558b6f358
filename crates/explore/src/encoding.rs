//! The compact encoding of an answer's curves (`"encoding": "f32"`). A curve's values `v_i` are
//! IEEE 754 float32 (a band's half-widths rounded further to [`BAND_BITS`] significant bits);
//! each is XORed with its prediction from the two before it, `p_0 = 0`, `p_1 = v_0`,
//! `p_i = f32(2 v_(i-1) - v_(i-2))` (0 where that is not finite); the four bytes of those words
//! are laid out as four planes (every word's lowest byte first, then every word's second
//! byte, ...) and written as base64 (RFC 4648, with padding). Float32 keeps 7 significant
//! digits, more than the page shows; the predictions and the planes turn what successive
//! values of a smooth curve share into runs of zeros, which the answer's compression then all
//! but removes. The page decodes it back into numbers (`codec.js`).

use base64::Engine;

/// Significant bits of a band's half-width: each within 1/4096 of itself, far below a pixel
/// of the band's edge (the curve's own values keep float32's 24).
pub const BAND_BITS: u32 = 12;

/// Significant bits of a float32.
const F32_BITS: u32 = 24;

/// `x` as float32 rounded to `significant` bits (the nearest, ties away from zero).
fn rounded(x: f64, significant: u32) -> f32 {
    let v = x as f32;
    let drop = F32_BITS - significant.clamp(1, F32_BITS);
    if drop == 0 || !v.is_finite() {
        return v;
    }
    f32::from_bits(((v.to_bits() >> (drop - 1)) + 1) >> 1 << drop)
}

/// The prediction of value `i` from the values before it.
fn predicted(v: &[f32], i: usize) -> u32 {
    let p = match i {
        0 => 0.0,
        1 => v[0],
        _ => (2.0 * f64::from(v[i - 1]) - f64::from(v[i - 2])) as f32,
    };
    if p.is_finite() {
        p.to_bits()
    } else {
        0
    }
}

fn encode(values: &[f64], significant: u32) -> String {
    let v: Vec<f32> = values.iter().map(|&x| rounded(x, significant)).collect();
    let n = v.len();
    let mut planes = vec![0u8; 4 * n];
    for i in 0..n {
        let word = v[i].to_bits() ^ predicted(&v, i);
        for (j, byte) in word.to_le_bytes().into_iter().enumerate() {
            planes[j * n + i] = byte;
        }
    }
    base64::engine::general_purpose::STANDARD.encode(planes)
}

/// A curve's `values` as float32, compact.
pub fn f32_base64(values: &[f64]) -> String {
    encode(values, F32_BITS)
}

/// A band's half-widths as float32 of [`BAND_BITS`] significant bits, compact.
pub fn band_base64(values: &[f64]) -> String {
    encode(values, BAND_BITS)
}

/// The values of a compact curve; `None` when it is not one.
pub fn from_f32_base64(text: &str) -> Option<Vec<f32>> {
    let planes = base64::engine::general_purpose::STANDARD
        .decode(text)
        .ok()?;
    if planes.len() % 4 != 0 {
        return None;
    }
    let n = planes.len() / 4;
    let mut v: Vec<f32> = Vec::with_capacity(n);
    for i in 0..n {
        let word = u32::from_le_bytes([
            planes[i],
            planes[n + i],
            planes[2 * n + i],
            planes[3 * n + i],
        ]);
        let bits = word ^ predicted(&v, i);
        v.push(f32::from_bits(bits));
    }
    Some(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn curves_round_trip_through_float32_and_bands_keep_12_bits() {
        let x = [
            0.0,
            -1.5,
            1e-30,
            3.4e38,
            3.4e38,
            0.1,
            -2.0e5,
            f64::from(f32::MIN_POSITIVE),
            -0.0,
        ];
        let text = f32_base64(&x);
        assert_eq!(text.len(), (x.len() * 4).div_ceil(3) * 4);
        let back = from_f32_base64(&text).unwrap();
        assert_eq!(back.len(), x.len());
        for (a, b) in x.iter().zip(&back) {
            assert_eq!(b.to_bits(), (*a as f32).to_bits(), "{a}");
        }
        let smooth: Vec<f64> = (0..500)
            .map(|k| 1e-3 * (k as f64 * 0.01).sin() + 2e-3)
            .collect();
        let bands = from_f32_base64(&band_base64(&smooth)).unwrap();
        for (a, b) in smooth.iter().zip(&bands) {
            assert!((f64::from(*b) - a).abs() <= a.abs() / 4096.0, "{a} {b}");
            assert_eq!(b.to_bits() & 0xfff, 0, "only 12 significant bits: {b}");
        }
        // The layout, as codec.js reads it: 1, 2, 3, 5 predict 0, 1, 3, 4, so the words are
        // 3f800000, 7f800000, 0, 00200000, in planes.
        assert_eq!(
            base64::engine::general_purpose::STANDARD
                .decode(f32_base64(&[1.0, 2.0, 3.0, 5.0]))
                .unwrap(),
            [0, 0, 0, 0, 0, 0, 0, 0, 0x80, 0x80, 0, 0x20, 0x3f, 0x7f, 0, 0]
        );
        assert_eq!(
            f32_base64(&[1.0, 2.0, 3.0, 5.0]),
            "AAAAAAAAAACAgAAgP38AAA=="
        );
        assert_eq!(f32_base64(&[]), "");
        assert_eq!(from_f32_base64("AACA"), None);
    }
}
