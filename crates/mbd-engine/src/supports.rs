//! Periodic supports under a beam: at each of `N` support positions `x_j` a chain of masses
//! (levels `l = 0..L-1`, from the beam down) linked by spring-dampers, the last level on the
//! ground, optionally sheared to its neighbours (the track: fastener, sleeper, ballast with
//! shear, subgrade). Forces (N), displacements positive downward:
//! ```text
//! F_0j = k_0 (w(x_j) - z_0j) + c_0 (w'(x_j) - z_0j')               beam to level 0
//! F_lj = k_l (z_(l-1)j - z_lj) + c_l (z_(l-1)j' - z_lj')            level l-1 to level l
//! m_l z_lj'' = F_lj - F_(l+1)j                                     l < L-1
//! m_L z_Lj'' = F_Lj - k_g z_Lj - c_g z_Lj'
//!              - k_w (2 z_Lj - z_L(j-1) - z_L(j+1)) - c_w (2 z_Lj' - ...)      (ends fixed)
//! ```
//! and the beam receives `-F_0j` at `x_j`. The beam side of `F_0j`, `k_0 w(x_j) + c_0 w'(x_j)`,
//! is the *seat* term; the engine computes it and the modal loads `sum_j F_0j Y_k(x_j)` either by
//! sine transforms (uniform supports from `x = 0` over the whole beam) or by dense products.

use mbd_system::model::ModelSupports;

/// Accelerations of the levels and the top link forces, given the seat terms.
///
/// `seat[j] = k_0 w(x_j) + c_0 w'(x_j)`; `z`, `v`, `a` hold the levels one after the other
/// (`L N` values, level-major); `forces` is `L N` scratch whose first `N` values are the top link
/// forces `F_0j` on return.
pub fn chain(
    s: &ModelSupports,
    seat: &[f64],
    z: &[f64],
    v: &[f64],
    a: &mut [f64],
    forces: &mut [f64],
) {
    let n = s.count;
    let levels = s.levels.len();
    debug_assert!(
        z.len() == levels * n
            && v.len() == z.len()
            && a.len() == z.len()
            && forces.len() == z.len()
    );
    let last = levels - 1;
    let lv = &s.levels[last];
    let inv_last = 1.0 / lv.mass;
    let (k_w, c_w) = lv.shear.unwrap_or((0.0, 0.0));
    let (k_g, c_g) = s.ground;
    // The last level's own terms: ground and the shear's own-block part 2 k_w z + 2 c_w z'.
    let (k_self, c_self) = (k_g + 2.0 * k_w, c_g + 2.0 * c_w);
    let top = &s.levels[0];
    let (k0, c0) = (top.k, top.c);
    if levels == 2 {
        // The track's chain in one pass over the supports: plain zipped slices, no bounds
        // checks, vectorised.
        let (k1, c1) = (s.levels[1].k, s.levels[1].c);
        let inv0 = 1.0 / top.mass;
        let (z0, z1) = z.split_at(n);
        let (v0, v1) = v.split_at(n);
        let (a0, a1) = a.split_at_mut(n);
        let columns = seat.iter().zip(z0).zip(v0).zip(z1.iter().zip(v1));
        let outputs = forces[..n].iter_mut().zip(a0.iter_mut()).zip(a1.iter_mut());
        for ((((&seat, &zs), &vs), (&zb, &vb)), ((f_out, as_out), ab_out)) in columns.zip(outputs) {
            let ff = seat - k0 * zs - c0 * vs;
            let fb = k1 * (zs - zb) + c1 * (vs - vb);
            *f_out = ff;
            *as_out = (ff - fb) * inv0;
            *ab_out = (fb - k_self * zb - c_self * vb) * inv_last;
        }
    } else {
        // Link forces: F_0 from the seat, F_l between consecutive levels.
        for (((f, &seat), &z), &v) in forces[..n].iter_mut().zip(seat).zip(&z[..n]).zip(&v[..n]) {
            *f = seat - k0 * z - c0 * v;
        }
        for l in 1..levels {
            let (k, c) = (s.levels[l].k, s.levels[l].c);
            let (za, zh) = (&z[(l - 1) * n..l * n], &z[l * n..(l + 1) * n]);
            let (va, vh) = (&v[(l - 1) * n..l * n], &v[l * n..(l + 1) * n]);
            for ((f, (&za, &zh)), (&va, &vh)) in forces[l * n..(l + 1) * n]
                .iter_mut()
                .zip(za.iter().zip(zh))
                .zip(va.iter().zip(vh))
            {
                *f = k * (za - zh) + c * (va - vh);
            }
        }
        for l in 0..last {
            let inv = 1.0 / s.levels[l].mass;
            let (f_in, f_out) = forces.split_at(l * n + n);
            for ((a, &fi), &fo) in a[l * n..l * n + n]
                .iter_mut()
                .zip(&f_in[l * n..])
                .zip(&f_out[..n])
            {
                *a = (fi - fo) * inv;
            }
        }
        let r = last * n..last * n + n;
        for (((a, &f), &z), &v) in a[r.clone()]
            .iter_mut()
            .zip(&forces[r.clone()])
            .zip(&z[r.clone()])
            .zip(&v[r])
        {
            *a = (f - k_self * z - c_self * v) * inv_last;
        }
    }
    // Shear: the neighbours' part + k_w (z_(j-1) + z_(j+1)) + c_w (..'), blocks beyond the ends
    // fixed at zero.
    if lv.shear.is_some() && n >= 2 {
        let r = last * n..last * n + n;
        let (zl, vl) = (&z[r.clone()], &v[r.clone()]);
        let (kw, cw) = (k_w * inv_last, c_w * inv_last);
        let a = &mut a[r];
        a[0] += kw * zl[1] + cw * vl[1];
        a[n - 1] += kw * zl[n - 2] + cw * vl[n - 2];
        let left = zl[..n - 2].iter().zip(&vl[..n - 2]);
        let right = zl[2..].iter().zip(&vl[2..]);
        for (a, ((zl, vl), (zr, vr))) in a[1..n - 1].iter_mut().zip(left.zip(right)) {
            *a += kw * (zl + zr) + cw * (vl + vr);
        }
    }
}

/// Positions of the supports (m).
pub fn positions(s: &ModelSupports) -> Vec<f64> {
    (0..s.count)
        .map(|j| s.first + j as f64 * s.spacing)
        .collect()
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)] // matrix loops read best with indices
mod tests {
    use super::*;
    use mbd_system::model::ModelLevel;

    fn track(n: usize) -> ModelSupports {
        ModelSupports {
            spacing: 0.6,
            count: n,
            first: 0.0,
            levels: vec![
                ModelLevel {
                    mass: 237.0,
                    k: 4e7,
                    c: 4.5e4,
                    shear: None,
                },
                ModelLevel {
                    mass: 341.3,
                    k: 2.4e8,
                    c: 5.88e4,
                    shear: Some((7.8e7, 8e4)),
                },
            ],
            ground: (6.5e7, 3.1e4),
        }
    }

    /// The linear stiffness and damping matrices of the chain (levels' DOFs, beam held still)
    /// are symmetric: every link acts equally and oppositely, shear included.
    #[test]
    fn chain_matrices_are_symmetric() {
        let s = track(7);
        let n = 2 * 7;
        for velocity in [false, true] {
            let mut m = vec![vec![0.0; n]; n];
            for col in 0..n {
                let mut e = vec![0.0; n];
                e[col] = 1.0;
                let zero = vec![0.0; n];
                let (z, v) = if velocity { (&zero, &e) } else { (&e, &zero) };
                let (mut a, mut f) = (vec![0.0; n], vec![0.0; n]);
                chain(&s, &[0.0; 7], z, v, &mut a, &mut f);
                for row in 0..n {
                    let mass = s.levels[row / 7].mass;
                    m[row][col] = -a[row] * mass;
                }
            }
            for i in 0..n {
                assert!(m[i][i] > 0.0);
                for j in 0..n {
                    assert!(
                        (m[i][j] - m[j][i]).abs() <= 1e-9 * m[i][i].abs(),
                        "({i},{j})"
                    );
                }
            }
            let expect = if velocity { -8e4 } else { -7.8e7 };
            assert!((m[7][8] - expect).abs() < 1e-6);
        }
    }

    /// The fused two-level pass and the general level-by-level passes give the same forces
    /// (three levels with a massless-like stiff middle reduce to two only approximately, so
    /// compare each against the equations written out instead).
    #[test]
    fn both_passes_follow_the_chain_equations() {
        for levels in [2usize, 3] {
            let mut s = track(5);
            if levels == 3 {
                s.levels.insert(
                    1,
                    ModelLevel {
                        mass: 100.0,
                        k: 3e8,
                        c: 1e4,
                        shear: None,
                    },
                );
            }
            let n = 5 * levels;
            let z: Vec<f64> = (0..n).map(|i| 1e-4 * ((i * 7 % 11) as f64 - 5.0)).collect();
            let v: Vec<f64> = (0..n).map(|i| 1e-2 * ((i * 3 % 7) as f64 - 3.0)).collect();
            let seat: Vec<f64> = (0..5).map(|j| 1e3 * j as f64).collect();
            let (mut a, mut f) = (vec![0.0; n], vec![0.0; n]);
            chain(&s, &seat, &z, &v, &mut a, &mut f);
            for j in 0..5 {
                let zz = |l: usize| z[l * 5 + j];
                let vv = |l: usize| v[l * 5 + j];
                let mut link = vec![seat[j] - s.levels[0].k * zz(0) - s.levels[0].c * vv(0)];
                for l in 1..levels {
                    link.push(
                        s.levels[l].k * (zz(l - 1) - zz(l)) + s.levels[l].c * (vv(l - 1) - vv(l)),
                    );
                }
                for l in 0..levels - 1 {
                    let want = (link[l] - link[l + 1]) / s.levels[l].mass;
                    assert!((a[l * 5 + j] - want).abs() <= 1e-12 * want.abs().max(1.0));
                }
                let l = levels - 1;
                let (kw, cw) = s.levels[l].shear.unwrap();
                let nb = |d: isize| {
                    let i = j as isize + d;
                    if (0..5).contains(&i) {
                        (z[l * 5 + i as usize], v[l * 5 + i as usize])
                    } else {
                        (0.0, 0.0)
                    }
                };
                let ((zl, vl), (zr, vr)) = (nb(-1), nb(1));
                let want = (link[l]
                    - s.ground.0 * zz(l)
                    - s.ground.1 * vv(l)
                    - kw * (2.0 * zz(l) - zl - zr)
                    - cw * (2.0 * vv(l) - vl - vr))
                    / s.levels[l].mass;
                assert!(
                    (a[l * 5 + j] - want).abs() <= 1e-9 * want.abs().max(1.0),
                    "{} vs {want}",
                    a[l * 5 + j]
                );
                assert_eq!(f[j], link[0]);
            }
        }
    }
}
