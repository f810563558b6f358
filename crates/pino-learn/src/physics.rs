//! Derivatives of predictions and the ten vehicle ODE residuals, as candle tensors (f64).
//!
//! Central differences on interior points `n = 1..T-2` (`docs/learning.md`):
//! ```text
//! v_n = (u_{n+1} - u_{n-1}) / (2 dt),   a_n = (u_{n+1} - 2 u_n + u_{n-1}) / dt^2
//! ```
//! taken on z-scored values and scaled by the channel std (the mean cancels, so no precision
//! is lost to a large offset). Residuals in physical units (N or N m), equation order
//! `z_c, beta_c, z_t1, beta_t1, z_t2, beta_t2, z_w1..z_w4` (`vtcd::vehicle`):
//! ```text
//! R_0 = m_c a_zc + F_s1 + F_s2           R_1 = j_c a_bc - l_c (F_s1 - F_s2)
//! R_2 = m_t a_t1 - (F_s1 - F_p1 - F_p2)  R_3 = j_t a_bt1 - l_t (F_p1 - F_p2)
//! R_4 = m_t a_t2 - (F_s2 - F_p3 - F_p4)  R_5 = j_t a_bt2 - l_t (F_p3 - F_p4)
//! R_{5+i} = m_w a_wi - (F_pi + W - P_i),  P_i = (max(0, z_wi - z_ri - eta_i) / G)^{3/2}
//! ```
//! with half masses `m = M/2`, `W = (m_c + 2 m_t + 4 m_w) g / 4` and the Hertz constant `G` of
//! `vtcd::contact`.

use crate::norm::ChannelStats;
use crate::Result;
use candle_core::{DType, Tensor};

fn stats_tensor(values: &[f64], like: &Tensor) -> Result<Tensor> {
    Ok(Tensor::from_slice(
        values,
        (1, 1, values.len()),
        like.device(),
    )?)
}

/// De-normalised interior values, first and second differences of `u_n [B, T, C]`
/// (z-scored, any float dtype) with channel statistics `stats` (first C channels used):
/// three f64 tensors `[B, T-2, C]` in physical units.
pub fn derivatives(
    u_n: &Tensor,
    stats: &ChannelStats,
    dt: f64,
) -> Result<(Tensor, Tensor, Tensor)> {
    let (_, t, c) = u_n.dims3()?;
    let u = u_n.to_dtype(DType::F64)?;
    let std = stats_tensor(&stats.std[..c], &u)?;
    let mean = stats_tensor(&stats.mean[..c], &u)?;
    let prev = u.narrow(1, 0, t - 2)?;
    let mid = u.narrow(1, 1, t - 2)?;
    let next = u.narrow(1, 2, t - 2)?;
    let z = mid.broadcast_mul(&std)?.broadcast_add(&mean)?;
    let v = ((&next - &prev)? * (1.0 / (2.0 * dt)))?.broadcast_mul(&std)?;
    let a = ((&next - (&mid * 2.0)?)? + &prev)?
        .affine(1.0 / (dt * dt), 0.0)?
        .broadcast_mul(&std)?;
    Ok((z, v, a))
}

/// The ten residuals `R [B, T', 10]` (f64, N or N m) from physical `(z, v, a)`, each `[B, T', 10]`, rail
/// displacements `z_r [B, T', 4]`, irregularity `eta [B, T', 4]`, parameters `params [B, 14]`
/// (spec order, whole-vehicle masses), gravity `g` (m/s^2) and Hertz constant `hertz_g`
/// (m/N^(2/3)).
pub fn residuals(
    (z, v, a): (&Tensor, &Tensor, &Tensor),
    z_r: &Tensor,
    eta: &Tensor,
    params: &Tensor,
    g: f64,
    hertz_g: f64,
) -> Result<Tensor> {
    let (b, _, _) = z.dims3()?;
    let p = |k: usize| -> Result<Tensor> { Ok(params.narrow(1, k, 1)?.reshape((b, 1, 1))?) };
    let ch = |x: &Tensor, i: usize| -> Result<Tensor> { Ok(x.narrow(2, i, 1)?) };
    let (m_c, j_c, m_t, j_t, m_w) = (
        (p(0)? * 0.5)?,
        (p(1)? * 0.5)?,
        (p(2)? * 0.5)?,
        (p(3)? * 0.5)?,
        (p(4)? * 0.5)?,
    );
    let (k_p, c_p, k_s, c_s, l_c, l_t) = (p(5)?, p(6)?, p(7)?, p(8)?, p(9)?, p(10)?);
    let w_load = ((&m_c + (&m_t * 2.0)?)? + (&m_w * 4.0)?)?.affine(g / 4.0, 0.0)?;
    // Secondary deflection d = Z_c + sign l_c beta_c - Z_t (compression positive).
    let sec = |sign: f64, bogie: usize, x: &Tensor| -> Result<Tensor> {
        let pitch = ch(x, 1)?.broadcast_mul(&l_c)?;
        Ok(((ch(x, 0)? + (pitch * sign)?)? - ch(x, bogie)?)?)
    };
    // Primary deflection d = Z_t + sign l_t beta_t - Z_w.
    let pri = |sign: f64, bogie: usize, wheel: usize, x: &Tensor| -> Result<Tensor> {
        let pitch = ch(x, bogie + 1)?.broadcast_mul(&l_t)?;
        Ok(((ch(x, bogie)? + (pitch * sign)?)? - ch(x, wheel)?)?)
    };
    let fs = |sign, bogie| -> Result<Tensor> {
        Ok((sec(sign, bogie, z)?.broadcast_mul(&k_s)?
            + sec(sign, bogie, v)?.broadcast_mul(&c_s)?)?)
    };
    let fp = |sign, bogie, wheel| -> Result<Tensor> {
        Ok((pri(sign, bogie, wheel, z)?.broadcast_mul(&k_p)?
            + pri(sign, bogie, wheel, v)?.broadcast_mul(&c_p)?)?)
    };
    let (fs1, fs2) = (fs(-1.0, 2)?, fs(1.0, 4)?);
    let fp = [
        fp(-1.0, 2, 6)?,
        fp(1.0, 2, 7)?,
        fp(-1.0, 4, 8)?,
        fp(1.0, 4, 9)?,
    ];
    let acc = |i: usize, mass: &Tensor| -> Result<Tensor> { Ok(ch(a, i)?.broadcast_mul(mass)?) };
    let mut r = vec![
        (acc(0, &m_c)? + (&fs1 + &fs2)?)?,
        (acc(1, &j_c)? - (&fs1 - &fs2)?.broadcast_mul(&l_c)?)?,
        (acc(2, &m_t)? - ((&fs1 - &fp[0])? - &fp[1])?)?,
        (acc(3, &j_t)? - (&fp[0] - &fp[1])?.broadcast_mul(&l_t)?)?,
        (acc(4, &m_t)? - ((&fs2 - &fp[2])? - &fp[3])?)?,
        (acc(5, &j_t)? - (&fp[2] - &fp[3])?.broadcast_mul(&l_t)?)?,
    ];
    for (i, fpi) in fp.iter().enumerate() {
        let delta = ((ch(z, 6 + i)? - ch(z_r, i)?)? - ch(eta, i)?)?;
        // Hertz: P = (max(0, delta) / G)^{3/2}; zero (and zero gradient) once lifted off.
        let contact = delta.relu()?.affine(1.0 / hertz_g, 0.0)?.powf(1.5)?;
        let force = (fpi.broadcast_add(&w_load)? - contact)?;
        r.push((acc(6 + i, &m_w)? - force)?);
    }
    Ok(Tensor::cat(&r, 2)?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::Device;
    use vtcd::params::SampleParams;
    use vtcd::vehicle::Vehicle;

    #[test]
    fn tensor_residuals_equal_the_vtcd_reference() {
        // Random states (one time point, two samples with different parameters): the tensor
        // code must reproduce vtcd::Vehicle::residuals to f64 rounding (1e-9 relative of the
        // ~1e5 N wheel loads).
        let dev = Device::Cpu;
        let mut s = vtcd::rng::SampleStream::new(5, vtcd::rng::Purpose::Training, 77);
        let g = vtcd::contact::hertz_constant(0.43);
        for k in 0..2 {
            let mut p = SampleParams::NOMINAL.to_array();
            p.iter_mut().for_each(|x| *x *= s.uniform_in(0.8, 1.2));
            let veh = Vehicle::new(&SampleParams::from_array(p), 9.81);
            let z: [f64; 10] = std::array::from_fn(|i| {
                if i >= 6 {
                    9e-5 + 1e-5 * s.normal()
                } else {
                    1e-3 * s.normal()
                }
            });
            let v: [f64; 10] = std::array::from_fn(|_| 0.05 * s.normal());
            let a: [f64; 10] = std::array::from_fn(|_| 2.0 * s.normal());
            let zr: [f64; 4] = std::array::from_fn(|_| 2e-6 * s.normal());
            let eta: [f64; 4] =
                std::array::from_fn(|i| if i == 3 { 1.0 } else { 3e-6 * s.normal() });
            // Wheel 4 is lifted off (eta = 1 m): its contact force is zero.
            let pc: [f64; 4] =
                std::array::from_fn(|i| vtcd::contact::contact_force(z[6 + i] - zr[i] - eta[i], g));
            assert_eq!(pc[3], 0.0);
            let want = veh.residuals(&z, &v, &a, &pc);
            let t = |x: &[f64], c: usize| Tensor::from_slice(x, (1, 1, c), &dev).unwrap();
            let r = residuals(
                (&t(&z, 10), &t(&v, 10), &t(&a, 10)),
                &t(&zr, 4),
                &t(&eta, 4),
                &Tensor::from_slice(&p, (1, 14), &dev).unwrap(),
                9.81,
                g,
            )
            .unwrap()
            .flatten_all()
            .unwrap()
            .to_vec1::<f64>()
            .unwrap();
            for i in 0..10 {
                assert!(
                    (r[i] - want[i]).abs() <= 1e-9 * 1e5,
                    "sample {k} eq {i}: {} vs {}",
                    r[i],
                    want[i]
                );
            }
        }
    }

    #[test]
    fn central_differences_are_exact_on_quadratics() {
        // u = 3 + 2 t + 5 t^2 in normalised units, std 2, mean 1: v = 2 (2 + 10 t), a = 20.
        let dev = Device::Cpu;
        let dt = 0.01;
        let u: Vec<f64> = (0..6)
            .map(|n| {
                let t = n as f64 * dt;
                3.0 + 2.0 * t + 5.0 * t * t
            })
            .collect();
        let stats = ChannelStats {
            names: vec!["x".into()],
            mean: vec![1.0],
            std: vec![2.0],
        };
        let (z, v, a) = derivatives(
            &Tensor::from_vec(u.clone(), (1, 6, 1), &dev).unwrap(),
            &stats,
            dt,
        )
        .unwrap();
        let (z, v, a) = (
            z.flatten_all().unwrap().to_vec1::<f64>().unwrap(),
            v.flatten_all().unwrap().to_vec1::<f64>().unwrap(),
            a.flatten_all().unwrap().to_vec1::<f64>().unwrap(),
        );
        for n in 1..5 {
            let t = n as f64 * dt;
            assert!((z[n - 1] - (1.0 + 2.0 * u[n])).abs() < 1e-12);
            assert!((v[n - 1] - 2.0 * (2.0 + 10.0 * t)).abs() < 1e-9);
            assert!((a[n - 1] - 20.0).abs() < 1e-7, "{}", a[n - 1]);
        }
    }
}
