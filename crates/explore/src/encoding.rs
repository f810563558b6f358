//! The compact encoding of an answer's curves (`"encoding": "f32"`): each curve's values as
//! IEEE 754 float32, each XORed with the one before it (the first with 0), the four bytes of
//! those words laid out as four planes (every word's lowest byte first, then every word's
//! second byte, ...), as base64 text (RFC 4648, with padding). Float32 keeps 7 significant
//! digits, more than the page shows; the XORs and the planes put the bytes successive values
//! share (sign, exponent, leading digits) side by side as runs of zeros, which the answer's
//! compression then all but removes. The page decodes it back into numbers (`codec.js`).

use base64::Engine;

/// `values` as float32, XORed in turn, in byte planes, base64.
pub fn f32_base64(values: &[f64]) -> String {
    let n = values.len();
    let mut planes = vec![0u8; 4 * n];
    let mut previous = 0u32;
    for (i, &v) in values.iter().enumerate() {
        let bits = (v as f32).to_bits();
        let word = bits ^ previous;
        previous = bits;
        for (j, byte) in word.to_le_bytes().into_iter().enumerate() {
            planes[j * n + i] = byte;
        }
    }
    base64::engine::general_purpose::STANDARD.encode(planes)
}

/// The values of an [`f32_base64`] text; `None` when it is not one.
pub fn from_f32_base64(text: &str) -> Option<Vec<f32>> {
    let planes = base64::engine::general_purpose::STANDARD
        .decode(text)
        .ok()?;
    if planes.len() % 4 != 0 {
        return None;
    }
    let n = planes.len() / 4;
    let mut previous = 0u32;
    Some(
        (0..n)
            .map(|i| {
                let word = u32::from_le_bytes([
                    planes[i],
                    planes[n + i],
                    planes[2 * n + i],
                    planes[3 * n + i],
                ]);
                previous ^= word;
                f32::from_bits(previous)
            })
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn curves_round_trip_through_float32_and_base64() {
        let x = [
            0.0,
            -1.5,
            1e-30,
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
            assert!((f64::from(*b) - a).abs() <= a.abs() * 6e-8, "{a} {b}");
        }
        // The layout: 1.0f32 is 0x3f800000; alone, its planes are 00 00 80 3f.
        assert_eq!(f32_base64(&[1.0]), "AACAPw==");
        // Two equal values: the second XOR is all zeros, planes [00 00] [00 00] [80 00] [3f 00].
        assert_eq!(
            from_f32_base64(&f32_base64(&[1.0, 1.0])).unwrap(),
            [1.0, 1.0]
        );
        assert_eq!(
            base64::engine::general_purpose::STANDARD
                .decode(f32_base64(&[1.0, 1.0]))
                .unwrap(),
            [0, 0, 0, 0, 0x80, 0, 0x3f, 0]
        );
        assert_eq!(f32_base64(&[]), "");
        assert_eq!(from_f32_base64("AACA"), None);
    }
}
