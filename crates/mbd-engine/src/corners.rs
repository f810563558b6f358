//! The corners of the box of sampling ranges: the designs at which the checks over the whole
//! box (the time-step bound, [`crate::stability::parameter_box`]; the profile starts and
//! reaches, [`crate::coverage`]) assemble and examine a model.

/// Most corners of a parameter box the box checks visit (`2^16`); beyond, it visits
/// that many corners drawn from a fixed sequence.
pub const MAX_CORNERS: usize = 1 << 16;

/// The corners of a box of `n` sampled parameters that the box checks visit, as masks (bit
/// `j % 64` set: parameter `j` at its maximum): all `2^n` up to 16 parameters, else
/// [`MAX_CORNERS`] drawn from a fixed sequence (deterministic).
pub fn box_corners(n: usize) -> Vec<u64> {
    if n <= 16 {
        (0..1u64 << n).collect()
    } else {
        // A fixed odd-multiplier sequence of corner masks (splitmix64).
        let mut z = 0x9e37_79b9_7f4a_7c15u64;
        (0..MAX_CORNERS)
            .map(|_| {
                z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
                let mut x = z;
                x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
                x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
                x ^ (x >> 31)
            })
            .collect()
    }
}

/// The design at corner `mask` ([`box_corners`]) of `system`'s box of sampling ranges
/// (`ranges`: [`mbd_system::System::ranges`]).
pub fn corner_values(
    system: &mbd_system::System,
    ranges: &[[f64; 2]],
    mask: u64,
) -> mbd_system::Sampled {
    let values: Vec<f64> = ranges
        .iter()
        .enumerate()
        .map(|(j, r)| r[((mask >> (j % 64)) & 1) as usize])
        .collect();
    system
        .sampled_values(values)
        .expect("one sampling range per sampled parameter")
}
