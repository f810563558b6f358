//! Per-channel errors in physical units (`channel_errors.*`): relative L2, RMS in an
//! engineer's unit, the worst sample and, for forces, the peak error as a share of W.

use crate::Result;
use pino_learn::checkpoint::ModelMeta;
use pino_learn::data::Prepared;
use pino_learn::layout::Layout;
use pino_outputs::physical::{exact_physical, Physical};

/// Display unit and scale of a displacement channel of unit `unit` (m or rad) at derivative
/// `order`: displacements mm, angles mrad, their rates per s, accelerations SI.
pub(crate) fn unit_of(unit: &str, order: usize) -> (&'static str, f64) {
    let angle = unit == "rad";
    match (order, angle) {
        (0, false) => ("mm", 1e3),
        (0, true) => ("mrad", 1e3),
        (1, false) => ("mm/s", 1e3),
        (1, true) => ("mrad/s", 1e3),
        (_, false) => ("m/s^2", 1.0),
        (_, true) => ("rad/s^2", 1.0),
    }
}

/// One channel's error.
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelError {
    /// Column name (`z_c`, `z_c_v`, ...).
    pub channel: String,
    /// Unit of the RMS values.
    pub unit: String,
    /// Mean relative L2 (%) in physical units.
    pub rel_l2_pct: f64,
    /// RMS error over all samples and times, in `unit`.
    pub rms_error: f64,
    /// RMS of the exact signal, in `unit`.
    pub rms_exact: f64,
    /// Sample with the largest relative error.
    pub worst_sample: i64,
    /// Its relative error (%).
    pub worst_rel_l2_pct: f64,
    /// Forces only: mean over samples of `|max_t pred - max_t exact|`, % of the sample's
    /// static contact force (W).
    pub peak_error_pct_w: Option<f64>,
}

/// Relative L2 per sample, RMS error and RMS exact (in `scale` units), worst sample, and
/// the mean peak error `|max_t pred - max_t exact|` as % of each sample's `w` (forces).
pub(super) struct Accum {
    rels: Vec<f64>,
    se: f64,
    sx: f64,
    n: usize,
    peaks: Vec<f64>,
}

impl Accum {
    fn new() -> Self {
        Self {
            rels: Vec::new(),
            se: 0.0,
            sx: 0.0,
            n: 0,
            peaks: Vec::new(),
        }
    }

    /// Adds one sample's series (already in display units).
    fn add(&mut self, exact: impl Iterator<Item = f64>, pred: impl Iterator<Item = f64>) {
        let (mut e2, mut x2, mut rows) = (0.0, 0.0, 0usize);
        let (mut pmax, mut xmax) = (f64::NEG_INFINITY, f64::NEG_INFINITY);
        for (x, p) in exact.zip(pred) {
            e2 += (p - x) * (p - x);
            x2 += x * x;
            rows += 1;
            pmax = pmax.max(p);
            xmax = xmax.max(x);
        }
        self.rels
            .push(if x2 > 0.0 { (e2 / x2).sqrt() } else { f64::NAN });
        self.se += e2;
        self.sx += x2;
        self.n += rows;
        self.peaks.push((pmax - xmax).abs());
    }

    fn finish(
        self,
        channel: String,
        unit: &str,
        ids: &[i64],
        peak_scale: Option<&[f64]>,
    ) -> ChannelError {
        let (worst, worst_rel) = self
            .rels
            .iter()
            .enumerate()
            .filter(|(_, r)| r.is_finite())
            .fold((usize::MAX, f64::NAN), |(bi, bv), (i, &r)| {
                if bi == usize::MAX || r > bv {
                    (i, r)
                } else {
                    (bi, bv)
                }
            });
        let finite: Vec<f64> = self
            .rels
            .iter()
            .copied()
            .filter(|r| r.is_finite())
            .collect();
        let n = self.n.max(1) as f64;
        ChannelError {
            channel,
            unit: unit.to_owned(),
            rel_l2_pct: 100.0 * finite.iter().sum::<f64>() / finite.len().max(1) as f64,
            rms_error: (self.se / n).sqrt(),
            rms_exact: (self.sx / n).sqrt(),
            worst_sample: ids.get(worst).copied().unwrap_or(-1),
            worst_rel_l2_pct: 100.0 * worst_rel,
            peak_error_pct_w: peak_scale.map(|w| {
                100.0 * self.peaks.iter().zip(w).map(|(e, w)| e / w).sum::<f64>()
                    / self.peaks.len().max(1) as f64
            }),
        }
    }
}

/// Display name, unit and scale of output channel `c` at derivative `order`.
pub(super) fn channel_label(
    layout: &Layout,
    c: usize,
    order: usize,
) -> (String, &'static str, f64) {
    let base = &layout.outputs[c];
    if layout.forces().contains(&c) {
        return (base.clone(), "kN", 1e-3);
    }
    if let Some(rate) = layout.rate_order(c) {
        // A rate the network outputs directly (labelled apart from the difference of its
        // displacement, which keeps the plain name).
        let stem = if layout.unit(base).starts_with("rad") {
            "rad"
        } else {
            "m"
        };
        let (unit, scale) = unit_of(stem, rate.into());
        return (layout.output_label(c), unit, scale);
    }
    let (unit, scale) = unit_of(layout.unit(base), order);
    let name = match order {
        0 => base.clone(),
        1 => format!("{base}_v"),
        _ => format!("{base}_a"),
    };
    (name, unit, scale)
}

/// Per-channel errors in physical units over the scored samples `idx` of `items`: every
/// output (forces in kN, predicted directly), the DOFs' velocities and accelerations, and for
/// each Hertz contact whose deflection the model predicts, `<force>_hertz`, the force of the
/// predicted deflection with the exact excitation (the displacement-implied route, kept for
/// comparison). Force rows also carry the mean peak-force error as % of each sample's static
/// contact force.
pub(super) fn channel_errors(
    items: &Prepared,
    idx: &[usize],
    preds: &[Physical],
    meta: &ModelMeta,
    system: &mbd_system::System,
) -> Result<Vec<ChannelError>> {
    let t = items.t_points();
    let layout = &meta.layout;
    let (o, d) = (layout.n_outputs(), layout.n_dofs());
    let ids: Vec<i64> = idx.iter().map(|&i| items.id(i)).collect();
    let (exact, etas): (Vec<Physical>, Vec<Vec<f64>>) = idx
        .iter()
        .map(|&i| exact_physical(items, i, &meta.norm))
        .collect::<Result<Vec<_>>>()?
        .into_iter()
        .unzip();
    let w_kn: Vec<f64> = idx.iter().map(|&i| items.force_scale(i) * 1e-3).collect();
    let mut out = Vec::new();
    for order in 0..3 {
        let nch = if order == 0 { o } else { d };
        for c in 0..nch {
            let (channel, unit, scale) = channel_label(layout, c, order);
            let mut acc = Accum::new();
            for (k, ex) in exact.iter().enumerate() {
                let (x, p, rows, off): (&[f64], &[f64], usize, usize) = match order {
                    0 => (&ex.u, &preds[k].u, t, 0),
                    1 => (&ex.v, &preds[k].v, t - 2, 1),
                    _ => (&ex.a, &preds[k].a, t - 2, 1),
                };
                acc.add(
                    (0..rows).map(|r| scale * x[(r + off) * nch + c]),
                    (0..rows).map(|r| scale * p[r * nch + c]),
                );
            }
            let force = order == 0 && layout.forces().contains(&c);
            out.push(acc.finish(channel, unit, &ids, force.then_some(w_kn.as_slice())));
        }
    }
    // Displacement-implied forces (kN): each Hertz contact's law at the predicted deflection.
    let map = pino_learn::residual::ChannelMap::new(system, layout);
    let e = layout.n_excitations();
    for (el, element) in system.elements.iter().enumerate() {
        let force_name = format!("p_{}", element.name);
        let (Some(fc), mbd_system::system::Law::Hertz { .. }) = (
            layout.outputs.iter().position(|x| *x == force_name),
            &element.law,
        ) else {
            continue;
        };
        let mut acc = Accum::new();
        let mut complete = true;
        for (k, &i) in idx.iter().enumerate() {
            let eq = pino_learn::residual::sample_equations(
                system,
                &system.sampled_values(items.params(i))?,
                Vec::new(),
            )?;
            let Some(deflection) = map.deflection(&eq, el) else {
                complete = false;
                break;
            };
            let law = eq.law(el);
            let (u, eta) = (&preds[k].u, &etas[k]);
            acc.add(
                (0..t).map(|r| 1e-3 * exact[k].u[r * o + fc]),
                (0..t).map(|r| {
                    let d = deflection.at(&u[r * o..(r + 1) * o], &eta[r * e..(r + 1) * e]);
                    1e-3 * law.force(d, 0.0)
                }),
            );
        }
        if complete {
            out.push(acc.finish(format!("{force_name}_hertz"), "kN", &ids, Some(&w_kn)));
        }
    }
    Ok(out)
}

/// Mean over the directly predicted forces of their peak error (% of the static contact force).
pub(super) fn peak_force_error(channels: &[ChannelError], layout: &Layout) -> f64 {
    let forces = &layout.outputs[layout.forces()];
    let v: Vec<f64> = channels
        .iter()
        .filter(|c| forces.contains(&c.channel))
        .filter_map(|c| c.peak_error_pct_w)
        .collect();
    if v.is_empty() {
        return f64::NAN;
    }
    v.iter().sum::<f64>() / v.len() as f64
}
