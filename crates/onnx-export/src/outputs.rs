//! The whole graph of a surrogate and its metadata.
//!
//! Outputs (`B` designs, `T` window points, `C` channels, `I` indices, `L` levels, `P`
//! parameters; every number double unless said):
//!
//! | output | shape | |
//! |---|---|---|
//! | `channels` | `[B, T-2, C]` | every predicted channel at the window's interior points (`predict --out`'s rows) |
//! | `channels_lo`, `channels_hi` | `[B, L, T-2, C]` | its calibrated band at each level |
//! | `indices` | `[B, I]` | the exported indices |
//! | `indices_lo`, `indices_hi` | `[B, L, I]` | their calibrated intervals |
//! | `verdicts` | `[B, L, I]` int32 | 0 pass, 1 uncertain, 2 fail, -1 no limit |
//! | `outside_training_range` | `[B, P]` bool | each parameter outside its training range |
//! | `extrapolated` | `[B]` bool | any is |
//!
//! The interval outputs exist only when every member has a calibration with intervals.

use crate::expr::Expressions;
use crate::graph::{encode, Graph, Value};
use crate::indices::IndexInputs;
use crate::intervals::{graph_normaliser, head_sigma, outside, quantiles, verdicts};
use crate::member::{self, Prediction, Series};
use crate::network::Weights;
use crate::proto::DataType;
use crate::{Error, ExportSpec, Result, Spectral};
use candle_core::Device;
use pino_calibration::{max_coverage, Calibration, Normaliser};
use pino_learn::checkpoint::load_model;
use pino_learn::spectral::Transform;
use pino_predict::Predictor;
use serde_json::json;
use std::path::PathBuf;

/// The format tag of the metadata.
pub const FORMAT: &str = "pino-mbd onnx 1";

/// The encoded file and what it holds.
#[derive(Debug, Clone)]
pub struct Exported {
    /// The ONNX file's bytes.
    pub bytes: Vec<u8>,
    /// What it holds.
    pub summary: Summary,
}

/// What an exported file holds.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// Channel names.
    pub channels: Vec<String>,
    /// Exported index names.
    pub indices: Vec<String>,
    /// Indices left out, with the reason.
    pub left_out: Vec<(String, String)>,
    /// Interval levels (empty without intervals).
    pub levels: Vec<f64>,
    /// The intervals' normaliser.
    pub normaliser: Option<Normaliser>,
    /// Why there are no intervals.
    pub no_intervals: Option<String>,
    /// The spectral form.
    pub spectral: Spectral,
    /// Nodes in the graph.
    pub nodes: usize,
}

/// One loaded member.
struct Member {
    key: String,
    dir: PathBuf,
    predictor: Predictor,
    weights: Weights,
}

fn load(spec: &crate::MemberSpec) -> Result<Member> {
    let dev = Device::Cpu;
    let mut predictor = Predictor::load(&spec.model, &dev)?;
    if let Some(c) = &spec.calibration {
        predictor.load_calibration(c)?;
    }
    let (model, _) = load_model(&spec.model, Transform::Matmul, &dev)?;
    let mut weights = Weights::new();
    for (name, t) in model.tensors() {
        let shape = t.dims().to_vec();
        let data = t
            .flatten_all()
            .and_then(|t| t.to_vec1::<f32>())
            .map_err(pino_learn::Error::from)?;
        weights.insert(name, (shape, data));
    }
    let key = if spec.key.is_empty() {
        format!("algorithm-{}", predictor.identity().algorithm)
    } else {
        spec.key.clone()
    };
    Ok(Member {
        key,
        dir: spec.model.clone(),
        predictor,
        weights,
    })
}

/// Members must share one design: the description, the parameters, the excitations and the
/// time grid.
fn check_members(members: &[Member]) -> Result<()> {
    let first = &members[0].predictor.meta;
    for m in &members[1..] {
        let meta = &m.predictor.meta;
        let same = meta.system == first.system
            && meta.layout.params == first.layout.params
            && meta.layout.excitations == first.layout.excitations
            && meta.grid == first.grid
            && meta.training_ranges == first.training_ranges;
        if !same {
            return Err(Error::Unsupported(format!(
                "member `{}` ({}) is not of the first member's design (description, parameters, excitations, time grid, training ranges)",
                m.key,
                m.dir.display()
            )));
        }
    }
    Ok(())
}

/// The calibration of every member, or why the file carries no interval.
fn calibrations(members: &[Member]) -> std::result::Result<Vec<&Calibration>, String> {
    members
        .iter()
        .map(|m| match m.predictor.calibration() {
            None => Err(format!("member `{}` has no calibration", m.key)),
            Some(c) if !c.has_intervals() => Err(format!(
                "member `{}`: {}",
                m.key,
                c.no_intervals
                    .clone()
                    .unwrap_or_else(|| "no calibration samples".into())
            )),
            Some(c) => Ok(c),
        })
        .collect()
}

/// Per member: where its channels lie and its index values, from the graph inputs.
struct Answers {
    channels: Vec<member::ChannelAt>,
    indices: Vec<std::result::Result<Value, String>>,
}

fn answers(g: &mut Graph, m: &Member, spectral: Spectral, inputs: (&str, &str)) -> Result<Answers> {
    let meta = &m.predictor.meta;
    let p: Prediction = member::predict(g, meta, &m.weights, spectral, inputs.0, inputs.1)?;
    let channels = member::channel_values(meta, &p);
    let inputs_ix = m.predictor.index_inputs();
    if inputs_ix.columns().is_empty() {
        return Ok(Answers {
            channels,
            indices: Vec::new(),
        });
    }
    let cfg = m.predictor.index_config()?;
    let grid = &meta.grid;
    let first = cfg.first_at(grid.t0, grid.dt).max(1);
    if first + 1 >= grid.t_points {
        return Err(Error::Unsupported(format!(
            "the description's `indices_from` leaves no point of the {}-point window",
            grid.t_points
        )));
    }
    let series: Series = member::index_series(g, &m.predictor, &p, first);
    let system = m.predictor.system().clone();
    let mut expressions = Expressions::new(&system, inputs.1.to_owned())?;
    let mut ix = IndexInputs {
        system: &system,
        expressions: &mut expressions,
        series: &series,
        points: grid.t_points - 1 - first,
        dt: grid.dt,
        config: &cfg,
        spectral,
    };
    let indices = ix.values(g);
    Ok(Answers { channels, indices })
}

/// Builds the graph and metadata of `spec`.
pub fn build(spec: &ExportSpec) -> Result<Exported> {
    if spec.members.is_empty() {
        return Err(Error::Unsupported("a surrogate without members".into()));
    }
    let members: Vec<Member> = spec.members.iter().map(load).collect::<Result<_>>()?;
    check_members(&members)?;
    let meta0 = &members[0].predictor.meta;
    let (p, e, t) = (
        meta0.layout.params.len(),
        meta0.layout.excitations.len(),
        meta0.grid.t_points,
    );
    let mut g = Graph::default();
    let params = g.input("parameters", DataType::Double, &[p]);
    let eta = g.input("excitation", DataType::Double, &[t, e]);
    let mut per_member = Vec::new();
    for m in &members {
        per_member.push(answers(&mut g, m, spec.spectral, (&eta, &params))?);
    }
    let plan = Plan::new(spec, &members, &per_member)?;
    let cals = calibrations(&members);
    let (outside_p, extrapolated) = outside(&mut g, &meta0.training_ranges, &params);
    let channels = plan.channels(&mut g, &per_member);
    g.output(
        "channels",
        &channels,
        DataType::Double,
        &[plan.rows, plan.channels.len()],
    );
    let indices = if plan.indices.is_empty() {
        String::new()
    } else {
        let v = plan.indices(&mut g, &per_member);
        g.output("indices", &v, DataType::Double, &[plan.indices.len()]);
        v
    };
    let mut summary = plan.summary(spec.spectral);
    match &cals {
        Ok(cals) => {
            let (levels, normaliser) = intervals(
                &mut g,
                &plan,
                spec,
                &members,
                cals,
                (&channels, &indices),
                &params,
                &extrapolated,
            )?;
            summary.levels = levels;
            summary.normaliser = Some(normaliser);
        }
        Err(why) => summary.no_intervals = Some(why.clone()),
    }
    g.output("outside_training_range", &outside_p, DataType::Bool, &[p]);
    g.output("extrapolated", &extrapolated, DataType::Bool, &[]);
    summary.nodes = g.len();
    let metadata = metadata(&members, &plan, &summary, cals.as_deref().ok())?;
    let doc = format!(
        "pino-mbd surrogate of `{}`: {} channels, {} indices{}",
        members[0].predictor.system().name,
        summary.channels.len(),
        summary.indices.len(),
        if summary.levels.is_empty() {
            ", no intervals".to_owned()
        } else {
            format!(", intervals at {:?}", summary.levels)
        }
    );
    let bytes = encode(
        g,
        spec.spectral.ir_version(),
        spec.spectral.opset(),
        "pino_mbd_surrogate",
        &doc,
        &metadata,
    );
    Ok(Exported { bytes, summary })
}

/// Which member answers each output quantity, and where it sits in that member's answers.
struct Plan {
    /// `(name, unit, member, position in the member's channels, its band)`.
    channels: Vec<(String, String, usize, usize, usize)>,
    /// `(name, unit, definition, member, position in the member's index columns)`.
    indices: Vec<(String, String, String, usize, usize)>,
    /// Indices the graph cannot compute, with the reason.
    left_out: Vec<(String, String)>,
    /// Interior window points `T-2`.
    rows: usize,
}

impl Plan {
    fn new(spec: &ExportSpec, members: &[Member], answers: &[Answers]) -> Result<Self> {
        let route = |routes: &[(String, usize)], name: &str| -> Result<usize> {
            let m = routes.iter().find(|(n, _)| n == name).map_or(0, |r| r.1);
            if m >= members.len() {
                return Err(Error::Unsupported(format!(
                    "`{name}` is routed to member {m}, the surrogate has {}",
                    members.len()
                )));
            }
            Ok(m)
        };
        let meta0 = &members[0].predictor.meta;
        let mut channels = Vec::new();
        for (name, _) in member::channels(meta0) {
            let m = route(&spec.channel_routes, &name)?;
            let mine = member::channels(&members[m].predictor.meta);
            let pos = mine.iter().position(|(n, _)| *n == name).ok_or_else(|| {
                Error::Unsupported(format!(
                    "member `{}` has no channel `{name}`",
                    members[m].key
                ))
            })?;
            let unit = meta0.layout.unit(&name).to_owned();
            channels.push((name, unit, m, pos, mine[pos].1));
        }
        let columns = members[0].predictor.index_inputs().columns();
        let mut indices = Vec::new();
        let mut left_out = Vec::new();
        for (k, c) in columns.iter().enumerate() {
            let m = route(&spec.index_routes, &c.name)?;
            match answers[m].indices.get(k) {
                Some(Ok(_)) => {
                    indices.push((c.name.clone(), c.unit.clone(), c.definition.clone(), m, k))
                }
                Some(Err(why)) => left_out.push((c.name.clone(), why.clone())),
                None => left_out.push((c.name.clone(), "not computed".into())),
            }
        }
        if let Some(asked) = &spec.indices {
            for name in asked {
                if let Some((_, why)) = left_out.iter().find(|(n, _)| n == name) {
                    return Err(Error::Unsupported(format!("index `{name}`: {why}")));
                }
                if !indices.iter().any(|i| i.0 == *name) {
                    let known: Vec<&str> = columns.iter().map(|c| c.name.as_str()).collect();
                    return Err(Error::Unsupported(format!(
                        "index `{name}` is not one of the description's ({})",
                        known.join(", ")
                    )));
                }
            }
            indices.retain(|i| asked.contains(&i.0));
        }
        Ok(Self {
            channels,
            indices,
            left_out,
            rows: meta0.grid.t_points - 2,
        })
    }

    /// The channels `[B, T-2, C]`, each from the member answering it.
    fn channels(&self, g: &mut Graph, answers: &[Answers]) -> Value {
        let picked: Vec<&member::ChannelAt> = self
            .channels
            .iter()
            .map(|c| &answers[c.2].channels[c.3])
            .collect();
        member::assemble_channels(g, &picked, self.rows + 2)
    }

    /// The indices `[B, I]`.
    fn indices(&self, g: &mut Graph, answers: &[Answers]) -> Value {
        let parts: Vec<Value> = self
            .indices
            .iter()
            .map(|i| match &answers[i.3].indices[i.4] {
                Ok(v) => g.unsqueeze(v, &[1]),
                Err(_) => unreachable!("left-out indices are not planned"),
            })
            .collect();
        let refs: Vec<&str> = parts.iter().map(String::as_str).collect();
        g.concat(1, &refs)
    }

    fn summary(&self, spectral: Spectral) -> Summary {
        Summary {
            channels: self.channels.iter().map(|c| c.0.clone()).collect(),
            indices: self.indices.iter().map(|i| i.0.clone()).collect(),
            left_out: self.left_out.clone(),
            levels: Vec::new(),
            normaliser: None,
            no_intervals: None,
            spectral,
            nodes: 0,
        }
    }
}

/// The levels of the intervals: those asked for, else the calibrations' reported levels that
/// every member's samples support; a level one cannot support is refused.
fn levels(spec: &ExportSpec, cals: &[&Calibration]) -> Result<Vec<f64>> {
    let supported = |l: f64| {
        cals.iter()
            .all(|c| l < 1.0 && l > 0.0 && l <= max_coverage(c.n))
    };
    match &spec.levels {
        Some(asked) => {
            for &l in asked {
                if !supported(l) {
                    let n = cals.iter().map(|c| c.n).min().unwrap_or(0);
                    return Err(Error::Unsupported(format!(
                        "level {l}: the calibration's {n} samples support levels in (0, {:.4}]",
                        max_coverage(n)
                    )));
                }
            }
            Ok(asked.clone())
        }
        None => Ok(cals[0]
            .levels
            .iter()
            .copied()
            .filter(|&l| supported(l))
            .collect()),
    }
}

/// Interval outputs: `channels_lo/hi`, `indices_lo/hi`, `verdicts`. Returns the levels and the
/// normaliser.
#[allow(clippy::too_many_arguments)]
fn intervals(
    g: &mut Graph,
    plan: &Plan,
    spec: &ExportSpec,
    members: &[Member],
    cals: &[&Calibration],
    values: (&str, &str),
    params: &str,
    extrapolated: &str,
) -> Result<(Vec<f64>, Normaliser)> {
    let levels = levels(spec, cals)?;
    let normaliser = graph_normaliser(cals[0], spec.normaliser)?;
    for c in &cals[1..] {
        graph_normaliser(c, Some(normaliser))?;
    }
    let l = levels.len();
    let (channels, indices) = values;
    // Channels: q [L, 1, C] (or with sigma [B, L, 1, C]) times scale [T-2, C].
    let n_c = plan.channels.len();
    let mut q = vec![0.0; l * n_c];
    let mut scale = vec![0.0; plan.rows * n_c];
    let mut qs = Vec::new();
    for (c, ch) in plan.channels.iter().enumerate() {
        let band = &cals[ch.2].channels[ch.4];
        for (k, v) in quantiles(&band.quantity, normaliser, &levels)?
            .into_iter()
            .enumerate()
        {
            q[k * n_c + c] = v;
        }
        for (r, s) in band.scale.iter().enumerate() {
            scale[r * n_c + c] = *s as f64;
        }
        qs.push(&band.quantity);
    }
    let scale = g.f64s(&[plan.rows, n_c], &scale);
    let half = match normaliser {
        Normaliser::ErrorHead => {
            let q = g.f64s(&[1, l, 1, n_c], &q);
            let sigma = head_sigma(g, &qs, params)?;
            let sigma = g.unsqueeze(&sigma, &[1, 2]);
            let w = g.mul(&q, &sigma);
            g.mul(&w, &scale)
        }
        _ => {
            let q = g.f64s(&[l, 1, n_c], &q);
            g.mul(&q, &scale)
        }
    };
    let f = g.unsqueeze(channels, &[1]);
    let lo = g.sub(&f, &half);
    let hi = g.add(&f, &half);
    g.output("channels_lo", &lo, DataType::Double, &[l, plan.rows, n_c]);
    g.output("channels_hi", &hi, DataType::Double, &[l, plan.rows, n_c]);
    if plan.indices.is_empty() {
        return Ok((levels, normaliser));
    }
    let n_i = plan.indices.len();
    let mut q = vec![0.0; l * n_i];
    let mut qs = Vec::new();
    for (i, ix) in plan.indices.iter().enumerate() {
        let score = &cals[ix.3].indices[ix.4];
        for (k, v) in quantiles(score, normaliser, &levels)?
            .into_iter()
            .enumerate()
        {
            q[k * n_i + i] = v;
        }
        qs.push(score);
    }
    let half = match normaliser {
        Normaliser::ErrorHead => {
            let q = g.f64s(&[1, l, n_i], &q);
            let sigma = head_sigma(g, &qs, params)?;
            let sigma = g.unsqueeze(&sigma, &[1]);
            g.mul(&q, &sigma)
        }
        _ => g.f64s(&[l, n_i], &q),
    };
    let f = g.unsqueeze(indices, &[1]);
    let lo = g.sub(&f, &half);
    let hi = g.add(&f, &half);
    g.output("indices_lo", &lo, DataType::Double, &[l, n_i]);
    g.output("indices_hi", &hi, DataType::Double, &[l, n_i]);
    let limits = index_limits(plan, members)?;
    let v = verdicts(g, &lo, &hi, &limits, extrapolated);
    g.output("verdicts", &v, DataType::Int32, &[l, n_i]);
    Ok((levels, normaliser))
}

/// The upper limit of each exported index (`predict`'s), from its member.
fn index_limits(plan: &Plan, members: &[Member]) -> Result<Vec<Option<f64>>> {
    plan.indices
        .iter()
        .map(|ix| {
            let p = &members[ix.3].predictor;
            let cfg = p.index_config()?;
            Ok(p.index_inputs().limits(p.system(), &cfg)[ix.4])
        })
        .collect()
}

/// The columns index `name` of `system` reads.
fn reads(system: &mbd_system::System, name: &str) -> Vec<String> {
    if let Some(ix) = system.indices.iter().find(|ix| ix.name == name) {
        return vec![system.channels[ix.channel].name.clone()];
    }
    let set = pino_indices::IndexSet::of(system);
    let Some(r) = set.railway else {
        return Vec::new();
    };
    match name {
        n if n.starts_with("peak_wheel") || n.starts_with("wheel_load") => r.p.to_vec(),
        n if n.starts_with("car_body") || n.starts_with("sperling") => vec![r.z_c_a, r.beta_c_a],
        n if n.starts_with("bogie") && n.contains("front") => vec![r.z_t_a[0].clone()],
        n if n.starts_with("bogie") => vec![r.z_t_a[1].clone()],
        _ => r.z_r.to_vec(),
    }
}

/// The file's metadata: `pino.format`, `pino.system_hash` and `pino.surrogate` (one JSON
/// document: members, inputs with the excitation recipe, outputs, intervals).
fn metadata(
    members: &[Member],
    plan: &Plan,
    summary: &Summary,
    cals: Option<&[&Calibration]>,
) -> Result<Vec<(String, String)>> {
    let p0 = &members[0].predictor;
    let meta = &p0.meta;
    let system = p0.system();
    let hash = meta.system.hash();
    let ranges = &meta.training_ranges;
    let nominal = system.nominal().into_values();
    let limits = if plan.indices.is_empty() {
        Vec::new()
    } else {
        index_limits(plan, members)?
    };
    let doc = json!({
        "format": FORMAT,
        "system": {"name": system.name, "hash": hash},
        "members": members.iter().enumerate().map(|(k, m)| {
            let id = m.predictor.identity();
            json!({"key": m.key, "blake3": id.blake3, "algorithm": id.algorithm,
                   "rate_outputs": m.predictor.meta.layout.rate_outputs(),
                   "calibration": cals.map(|c| json!({"n": c[k].n, "normaliser": c[k].normaliser.as_str(),
                                                      "head_inputs": c[k].head_inputs}))})
        }).collect::<Vec<_>>(),
        "spectral": summary.spectral.as_str(),
        "opset": summary.spectral.opset(),
        "inputs": {
            "parameters": {
                "shape": ["batch", ranges.names.len()],
                "names": ranges.names,
                "units": ranges.names.iter().map(|n| meta.layout.unit(n)).collect::<Vec<_>>(),
                "min": ranges.min, "max": ranges.max, "nominal": nominal,
            },
            "excitation": {
                "shape": ["batch", meta.grid.t_points, meta.layout.excitations.len()],
                "names": meta.layout.excitations,
                "units": meta.layout.excitations.iter().map(|n| meta.layout.unit(n)).collect::<Vec<_>>(),
                "recipe": crate::recipe::recipe(system, meta)?,
            },
        },
        "channels": plan.channels.iter().map(|c| {
            let m = &members[c.2].predictor.meta.layout;
            let (o, d) = (m.n_outputs(), m.n_dofs());
            let derived = (c.4 >= o).then(|| {
                let j = (c.4 - o) % d;
                json!({"of": m.dofs[j], "order": 1 + (c.4 - o) / d})
            });
            json!({"name": c.0, "unit": c.1, "member": c.2, "derived": derived})
        }).collect::<Vec<_>>(),
        "channel_times": {"first": meta.grid.t0 + meta.grid.dt, "dt": meta.grid.dt, "points": plan.rows},
        "indices": plan.indices.iter().zip(limits.iter().map(Some).chain(std::iter::repeat(None)))
            .map(|(i, l)| json!({"name": i.0, "unit": i.1, "definition": i.2, "member": i.3,
                                 "limit": l.copied().flatten(), "reads": reads(system, &i.0)}))
            .collect::<Vec<_>>(),
        "left_out": plan.left_out.iter().map(|(n, w)| json!({"name": n, "why": w})).collect::<Vec<_>>(),
        "intervals": match &summary.no_intervals {
            Some(why) => json!({"levels": [], "why": why}),
            None => json!({"levels": summary.levels,
                           "normaliser": summary.normaliser.map(|n| n.as_str()),
                           "product_normaliser": cals.map(|c| c[0].normaliser.as_str()),
                           "calibration_samples": cals.map(|c| c.iter().map(|c| c.n).min())}),
        },
    });
    Ok(vec![
        ("pino.format".into(), FORMAT.into()),
        ("pino.system_hash".into(), hash),
        ("pino.surrogate".into(), doc.to_string()),
    ])
}
