//! The declaration of one study and the stage's shared settings, checked against the model's
//! system before anything runs: unknown parameters and indices, numbers out of range and
//! study sizes beyond the stated limits are refused with the field named
//! (`study.<name>.<field>`).

use pino_studies::Distribution;
use serde::Deserialize;
use serde_json::Value;
use std::collections::BTreeMap;

/// The `kind` of a Monte Carlo study.
pub const MONTE_CARLO: &str = "monte_carlo";
/// The `kind` of a sensitivity study.
pub const SENSITIVITY: &str = "sensitivity";
/// The `kind` of an optimisation.
pub const OPTIMISE: &str = "optimise";
/// The `kind` of a critical-speed study.
pub const CRITICAL_SPEED: &str = "critical_speed";

/// The most points of a critical-speed study's grid per parameter and of its speed sweep.
pub const MAX_CRITICAL_SPEED_POINTS: usize = 101;

/// The most parameters a critical-speed study's grid spans.
pub const MAX_CRITICAL_SPEED_GRID: usize = 2;

/// The most excitations a critical-speed study averages each design's growth over.
pub const MAX_CRITICAL_SPEED_EXCITATIONS: usize = 64;

/// The most designs a Monte Carlo study evaluates.
pub const MAX_MONTE_CARLO: usize = 1_000_000;

/// The most evaluations (`N (factors + 2)`) a sensitivity study makes.
pub const MAX_SENSITIVITY_EVALUATIONS: usize = 1_000_000;

/// The fewest rows of a sensitivity study's design.
pub const MIN_SENSITIVITY_ROWS: usize = 4;

/// The name of the excitation as one grouped factor of a sensitivity study.
pub const EXCITATION_FACTOR: &str = "excitation";

/// The most excitations an optimisation averages each candidate over.
pub const MAX_OPTIMISE_EXCITATIONS: usize = 256;

/// The most starting points of an optimisation.
pub const MAX_OPTIMISE_STARTS: usize = 64;

/// The most candidates of an optimisation's history the solver checks beside the optimum
/// and the runners-up.
pub const MAX_OPTIMISE_SOLVER_CHECK: usize = 1000;

/// The most Nelder-Mead iterations per run of a start.
pub const MAX_OPTIMISE_ITERATIONS: u64 = 10_000;

/// The `study` stage's parameters: the study (the matrix value) and the settings shared by
/// every study.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StudyParams {
    /// The study's declaration (one matrix value).
    pub study: Value,
    /// The trained model used (its `algorithm`).
    #[serde(default = "default_algorithm")]
    pub algorithm: i64,
    /// Coverage of the calibrated intervals.
    #[serde(default = "default_coverage")]
    pub coverage: f64,
    /// Seed of the designs, excitations and bootstrap.
    #[serde(default = "default_seed")]
    pub seed: u64,
    /// Designs per forward pass.
    #[serde(default = "default_batch")]
    pub batch_size: usize,
    /// Bootstrap replicates of every interval.
    #[serde(default = "default_bootstrap")]
    pub bootstrap: usize,
    /// Level of the statistical intervals (bootstrap, Wilson).
    #[serde(default = "default_confidence")]
    pub confidence: f64,
    /// Where the network runs.
    #[serde(default = "default_device")]
    pub device: pino_learn::config::DeviceKind,
    /// Overrides of the description's values (checked against the description before the
    /// model exists).
    #[serde(default)]
    pub system_values: BTreeMap<String, mbd_system::Override>,
}

impl StudyParams {
    /// Checks the shared settings.
    pub fn validate(&self) -> crate::Result<()> {
        let bad = |field: &str, value: String, allowed: &str| pino_learn::Error::OutOfRange {
            field: field.into(),
            value,
            allowed: allowed.into(),
        };
        for (field, level) in [("coverage", self.coverage), ("confidence", self.confidence)] {
            pino_studies::stats::check_level(field, level)
                .map_err(|e| bad(field, level.to_string(), &e.to_string()))?;
        }
        if self.batch_size == 0 {
            return Err(bad("batch_size", "0".into(), ">= 1").into());
        }
        if self.bootstrap > 100_000 {
            return Err(bad(
                "bootstrap",
                self.bootstrap.to_string(),
                "0 to 100000 replicates",
            )
            .into());
        }
        Ok(())
    }
}

fn default_algorithm() -> i64 {
    5
}
fn default_coverage() -> f64 {
    0.9
}
fn default_seed() -> u64 {
    7
}
fn default_batch() -> usize {
    8
}
fn default_bootstrap() -> usize {
    1000
}
fn default_confidence() -> f64 {
    0.95
}
fn default_device() -> pino_learn::config::DeviceKind {
    pino_learn::config::DeviceKind::Cpu
}

/// One study, parsed.
#[derive(Debug, Clone, PartialEq)]
pub struct Study {
    /// Its name (the output's and the unit's).
    pub name: String,
    /// What it computes.
    pub kind: StudyKind,
    /// Parameter distributions by name, as declared (the rest uniform over the training
    /// range).
    pub parameters: BTreeMap<String, Distribution>,
    /// Designs also run through the solver.
    pub solver_check: usize,
}

/// The kinds of study.
#[derive(Debug, Clone, PartialEq)]
pub enum StudyKind {
    /// N designs drawn from the distributions, each under its own excitation.
    MonteCarlo {
        /// Designs.
        n: usize,
        /// Upper limits by index (the description's limits where not given).
        limits: BTreeMap<String, f64>,
    },
    /// Sobol indices of every index over every varying parameter and the excitation, on a
    /// Saltelli design of `n` rows (`n (factors + 2)` evaluations); the solver runs the
    /// design's first `solver_check` rows.
    Sensitivity {
        /// Rows of the design (a power of two).
        n: usize,
    },
    /// Minimise (or maximise) a weighted sum of indices under upper limits on indices, over
    /// the box of the uniform distributions (the training ranges by default), each candidate
    /// judged by a statistic over the same `excitations`.
    Optimise(Optimise),
    /// The speed at which a growth index (the lateral stability index) turns positive, at
    /// each point of a grid over one or two parameters: the speed swept over its training
    /// range, the other parameters at their distributions' medians.
    CriticalSpeed(CriticalSpeed),
}

/// What a critical-speed study sweeps.
#[derive(Debug, Clone, PartialEq)]
pub struct CriticalSpeed {
    /// The speed parameter (swept over its training range).
    pub speed: String,
    /// Points of the sweep (the range's ends included).
    pub speeds: usize,
    /// The grid: parameters and their points over their training ranges (ends included).
    pub grid: Vec<(String, usize)>,
    /// The growth index (positive: the oscillation grows).
    pub index: String,
    /// Excitations every design runs under (ids `0..excitations`); its growth is their mean.
    pub excitations: usize,
}

/// What an optimisation looks for.
#[derive(Debug, Clone, PartialEq)]
pub struct Optimise {
    /// The objective's terms: index name and weight (the objective is their weighted sum).
    pub objective: Vec<(String, f64)>,
    /// Whether the objective is maximised (else minimised).
    pub maximise: bool,
    /// Upper limits by index, judged on the upper end of the calibrated interval where the
    /// model has one (the description's limits where not given).
    pub limits: BTreeMap<String, f64>,
    /// Excitations every candidate is evaluated under (ids `0..excitations`).
    pub excitations: usize,
    /// The statistic over the excitations of the objective and of each constraint.
    pub statistic: Robust,
    /// Starting points (the box's centre first, the rest drawn).
    pub starts: usize,
    /// Nelder-Mead iterations per run (each start runs twice: first and restart).
    pub iterations: u64,
    /// Best points of other starts also checked by the solver.
    pub runners_up: usize,
}

/// A statistic over a candidate's excitations.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Robust {
    /// The mean.
    Mean,
    /// The `p`-quantile (linear interpolation).
    Quantile(f64),
}

impl Robust {
    /// The statistic of `values` (NaN when any is not finite).
    pub fn of(self, values: &[f64]) -> f64 {
        if values.iter().any(|v| !v.is_finite()) {
            return f64::NAN;
        }
        match self {
            Self::Mean => pino_studies::stats::mean(values),
            Self::Quantile(p) => {
                pino_studies::stats::quantile_sorted(&pino_studies::stats::sorted(values), p)
            }
        }
    }

    /// Its name in tables (`mean`, `q90`).
    pub fn label(self) -> String {
        match self {
            Self::Mean => "mean".into(),
            Self::Quantile(p) => format!("q{}", (p * 100.0).round() as i64),
        }
    }
}

/// A refusal naming the field.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("study.{study}.{field}: {message}")]
pub struct SpecError {
    /// The study's name (`?` before it is known).
    pub study: String,
    /// The field.
    pub field: String,
    /// What is wrong and what is allowed.
    pub message: String,
}

/// A parameter's distribution as written: `{uniform: [lo, hi]}`, `{normal: {mean, std}}`,
/// `{lognormal: {median, sigma_log}}` (truncated at `range: [lo, hi]`, by default the
/// training range), `{fixed: v}` or a bare number (fixed).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "snake_case")]
struct DistributionSpec {
    uniform: Option<[f64; 2]>,
    normal: Option<NormalSpec>,
    lognormal: Option<LogNormalSpec>,
    fixed: Option<f64>,
    range: Option<[f64; 2]>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct NormalSpec {
    mean: f64,
    std: f64,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct LogNormalSpec {
    median: f64,
    sigma_log: f64,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct SensitivitySpec {
    n: usize,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct OptimiseSpec {
    objective: Value,
    #[serde(default = "default_sense")]
    sense: String,
    #[serde(default)]
    limits: BTreeMap<String, f64>,
    #[serde(default = "default_excitations")]
    excitations: usize,
    #[serde(default = "default_statistic")]
    statistic: Value,
    #[serde(default = "default_starts")]
    starts: usize,
    #[serde(default = "default_iterations")]
    iterations: u64,
    #[serde(default = "default_runners_up")]
    runners_up: usize,
}

fn default_sense() -> String {
    "minimise".into()
}
fn default_excitations() -> usize {
    8
}
fn default_statistic() -> Value {
    Value::String("mean".into())
}
fn default_starts() -> usize {
    4
}
fn default_iterations() -> u64 {
    60
}
fn default_runners_up() -> usize {
    2
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct CriticalSpeedSpec {
    speed: String,
    grid: BTreeMap<String, usize>,
    #[serde(default = "default_speeds")]
    speeds: usize,
    #[serde(default = "default_growth_index")]
    index: String,
    #[serde(default = "default_critical_excitations")]
    excitations: usize,
}

fn default_speeds() -> usize {
    11
}
fn default_growth_index() -> String {
    pino_indices::lateral::STABILITY_INDEX.to_owned()
}
fn default_critical_excitations() -> usize {
    4
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct MonteCarloSpec {
    n: usize,
    #[serde(default)]
    limits: BTreeMap<String, f64>,
}

impl Study {
    /// Parses a study's declaration; `parameters` are the model's sampled parameters with
    /// their training ranges, `indices` its index names.
    pub fn parse(
        value: &Value,
        parameters: &[(String, [f64; 2])],
        indices: &[String],
    ) -> Result<Self, SpecError> {
        let Value::Object(map) = value else {
            return Err(SpecError {
                study: "?".into(),
                field: String::new(),
                message: "a study is a mapping with `name` and `kind`".into(),
            });
        };
        let name = study_name(map)?;
        let cx = ParseContext {
            name: &name,
            parameters,
            indices,
        };
        let mut rest = map.clone();
        rest.remove("name");
        let kind = rest.remove("kind");
        let solver_check = match rest.remove("solver_check") {
            None => 0,
            Some(v) => v
                .as_u64()
                .ok_or_else(|| cx.err("solver_check", format!("{v}: a count of designs >= 0")))?
                as usize,
        };
        let dists = cx.distributions(rest.remove("parameters"))?;
        let kind = match kind.as_ref().and_then(Value::as_str) {
            Some(MONTE_CARLO) => cx.monte_carlo(rest, solver_check)?,
            Some(SENSITIVITY) => cx.sensitivity(rest, &dists, solver_check)?,
            Some(OPTIMISE) => cx.optimise(rest, &dists, solver_check)?,
            Some(CRITICAL_SPEED) => cx.critical_speed(rest, &dists, solver_check)?,
            other => {
                return Err(cx.err(
                    "kind",
                    format!(
                    "{other:?}: one of {MONTE_CARLO}, {SENSITIVITY}, {OPTIMISE}, {CRITICAL_SPEED}"
                ),
                ))
            }
        };
        Ok(Self {
            name,
            kind,
            parameters: dists,
            solver_check,
        })
    }

    /// The distribution of every sampled parameter (declared, else uniform over its training
    /// range), in the model's parameter order.
    pub fn distributions(&self, parameters: &[(String, [f64; 2])]) -> Vec<Distribution> {
        parameters
            .iter()
            .map(|(n, [lo, hi])| {
                self.parameters
                    .get(n)
                    .copied()
                    .unwrap_or(Distribution::Uniform { lo: *lo, hi: *hi })
            })
            .collect()
    }
}

/// The study's `name`: letters, digits, `_` and `-`.
fn study_name(map: &serde_json::Map<String, Value>) -> Result<String, SpecError> {
    match map.get("name") {
        Some(Value::String(s))
            if !s.is_empty()
                && s.chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-') =>
        {
            Ok(s.clone())
        }
        other => Err(SpecError {
            study: "?".into(),
            field: "name".into(),
            message: format!("{other:?}: a name of letters, digits, `_` and `-`"),
        }),
    }
}

/// What a study's fields are checked against: its name (for messages), the model's sampled
/// parameters with their training ranges and its index names.
struct ParseContext<'a> {
    name: &'a str,
    parameters: &'a [(String, [f64; 2])],
    indices: &'a [String],
}

impl ParseContext<'_> {
    /// An error of this study's `field`.
    fn err(&self, field: &str, message: String) -> SpecError {
        SpecError {
            study: self.name.to_owned(),
            field: field.to_owned(),
            message,
        }
    }

    /// `i` (written in `field`) is an index of the model.
    fn check_index(&self, field: &str, i: &str) -> Result<(), SpecError> {
        if self.indices.iter().any(|x| x == i) {
            return Ok(());
        }
        Err(self.err(
            field,
            format!(
                "`{i}` is not an index of the model (indices: {})",
                self.indices.join(", ")
            ),
        ))
    }

    /// Upper limits by index: known indices, finite values.
    fn check_limits(&self, limits: &BTreeMap<String, f64>) -> Result<(), SpecError> {
        for (i, l) in limits {
            let field = format!("limits.{i}");
            self.check_index(&field, i)?;
            if !l.is_finite() {
                return Err(self.err(&field, format!("{l}: a finite limit")));
            }
        }
        Ok(())
    }

    /// The declared `parameters:`, each a sampled parameter of the model with a valid
    /// distribution.
    fn distributions(
        &self,
        declared: Option<Value>,
    ) -> Result<BTreeMap<String, Distribution>, SpecError> {
        let declared = match declared {
            None => serde_json::Map::new(),
            Some(Value::Object(p)) => p,
            Some(v) => {
                return Err(self.err(
                    "parameters",
                    format!("{v}: a mapping from parameter names to distributions"),
                ))
            }
        };
        let mut dists = BTreeMap::new();
        for (p, v) in declared {
            let field = format!("parameters.{p}");
            let Some((_, range)) = self.parameters.iter().find(|(n, _)| *n == p) else {
                let known: Vec<&str> = self.parameters.iter().map(|(n, _)| n.as_str()).collect();
                return Err(self.err(
                    &field,
                    format!(
                        "not a sampled parameter of the model (parameters: {})",
                        known.join(", ")
                    ),
                ));
            };
            let d = parse_distribution(&v, *range).map_err(|m| self.err(&field, m))?;
            d.validate(&field)
                .map_err(|e| self.err(&field, e.to_string()))?;
            dists.insert(p, d);
        }
        Ok(dists)
    }

    /// The fields of a `monte_carlo` study.
    fn monte_carlo(
        &self,
        rest: serde_json::Map<String, Value>,
        solver_check: usize,
    ) -> Result<StudyKind, SpecError> {
        let s: MonteCarloSpec =
            serde_json::from_value(Value::Object(rest)).map_err(|e| self.err("", e.to_string()))?;
        if !(1..=MAX_MONTE_CARLO).contains(&s.n) {
            return Err(self.err("n", format!("{}: allowed 1 to {MAX_MONTE_CARLO}", s.n)));
        }
        if solver_check > s.n {
            return Err(self.err(
                "solver_check",
                format!("{solver_check} is more than the study's {} designs", s.n),
            ));
        }
        self.check_limits(&s.limits)?;
        Ok(StudyKind::MonteCarlo {
            n: s.n,
            limits: s.limits,
        })
    }

    /// The fields of a `sensitivity` study: N a power of two within the evaluation budget
    /// of the varying factors.
    fn sensitivity(
        &self,
        rest: serde_json::Map<String, Value>,
        dists: &BTreeMap<String, Distribution>,
        solver_check: usize,
    ) -> Result<StudyKind, SpecError> {
        let s: SensitivitySpec =
            serde_json::from_value(Value::Object(rest)).map_err(|e| self.err("", e.to_string()))?;
        let varying = self
            .parameters
            .iter()
            .filter(|(p, _)| dists.get(p).is_none_or(Distribution::varies))
            .count();
        if varying == 0 {
            return Err(self.err(
                "parameters",
                "every parameter is fixed: a sensitivity study needs one that varies".into(),
            ));
        }
        let factors = varying + 1;
        let most = (MAX_SENSITIVITY_EVALUATIONS / (factors + 2)).min(pino_studies::sobol::MAX_ROWS);
        if !(MIN_SENSITIVITY_ROWS..=most).contains(&s.n) || !s.n.is_power_of_two() {
            return Err(self.err(
                "n",
                format!(
                    "{}: a power of two from {MIN_SENSITIVITY_ROWS} to {most} rows \
                     (N ({factors} factors + 2) evaluations, at most \
                     {MAX_SENSITIVITY_EVALUATIONS})",
                    s.n
                ),
            ));
        }
        if solver_check != 0 && (solver_check < 2 || !solver_check.is_power_of_two()) {
            return Err(self.err(
                "solver_check",
                format!(
                    "{solver_check}: 0 or a power of two >= 2 (rows of the design the \
                     solver also runs)"
                ),
            ));
        }
        if solver_check > s.n {
            return Err(self.err(
                "solver_check",
                format!("{solver_check} is more than the study's {} rows", s.n),
            ));
        }
        Ok(StudyKind::Sensitivity { n: s.n })
    }

    /// The fields of an `optimise` study: its objective and limits on known indices, a box
    /// (uniform or fixed parameters, one varying), a bounded solver check.
    fn optimise(
        &self,
        rest: serde_json::Map<String, Value>,
        dists: &BTreeMap<String, Distribution>,
        solver_check: usize,
    ) -> Result<StudyKind, SpecError> {
        let s: OptimiseSpec =
            serde_json::from_value(Value::Object(rest)).map_err(|e| self.err("", e.to_string()))?;
        let o = parse_optimise(s, &|field: &str, message: String| self.err(field, message))?;
        for (i, _) in &o.objective {
            self.check_index(&format!("objective.{i}"), i)?;
        }
        self.check_limits(&o.limits)?;
        for (p, d) in dists {
            if !matches!(d, Distribution::Uniform { .. } | Distribution::Fixed(_)) {
                return Err(self.err(
                    &format!("parameters.{p}"),
                    "an optimisation searches a box: `uniform: [lo, hi]` (a sub-box) or `fixed`"
                        .into(),
                ));
            }
        }
        if !dists.values().any(Distribution::varies) && dists.len() == self.parameters.len() {
            return Err(self.err(
                "parameters",
                "every parameter is fixed: an optimisation needs one that varies".into(),
            ));
        }
        if solver_check > MAX_OPTIMISE_SOLVER_CHECK {
            return Err(self.err(
                "solver_check",
                format!(
                    "{solver_check}: at most {MAX_OPTIMISE_SOLVER_CHECK} candidates of the \
                     history (beside the optimum and the runners-up)"
                ),
            ));
        }
        Ok(StudyKind::Optimise(o))
    }
}

impl ParseContext<'_> {
    /// The fields of a `critical_speed` study: a sampled speed, one or two other sampled
    /// parameters for the grid (not fixed by `parameters:`), point counts within bounds, a
    /// known growth index, a solver check of at most the grid's points.
    fn critical_speed(
        &self,
        rest: serde_json::Map<String, Value>,
        dists: &BTreeMap<String, Distribution>,
        solver_check: usize,
    ) -> Result<StudyKind, SpecError> {
        let s: CriticalSpeedSpec =
            serde_json::from_value(Value::Object(rest)).map_err(|e| self.err("", e.to_string()))?;
        let swept = |field: &str, p: &str| -> Result<(), SpecError> {
            let known = self.parameters.iter().find(|(n, _)| n == p);
            match known {
                None => Err(self.err(
                    field,
                    format!(
                        "`{p}` is not a sampled parameter of the model (parameters: {})",
                        self.parameters
                            .iter()
                            .map(|(n, _)| n.as_str())
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                )),
                Some((_, [lo, hi])) if !(lo.is_finite() && hi.is_finite() && lo < hi) => Err(self
                    .err(
                        field,
                        format!("`{p}` has no finite training range to sweep"),
                    )),
                Some(_) if dists.contains_key(p) => Err(self.err(
                    field,
                    format!("`{p}` is swept over its training range: leave it out of `parameters`"),
                )),
                Some(_) => Ok(()),
            }
        };
        let points = |field: &str, n: usize, least: usize| -> Result<(), SpecError> {
            if (least..=MAX_CRITICAL_SPEED_POINTS).contains(&n) {
                Ok(())
            } else {
                Err(self.err(
                    field,
                    format!("{n}: allowed {least} to {MAX_CRITICAL_SPEED_POINTS} points"),
                ))
            }
        };
        swept("speed", &s.speed)?;
        points("speeds", s.speeds, 3)?;
        if !(1..=MAX_CRITICAL_SPEED_GRID).contains(&s.grid.len()) {
            return Err(self.err(
                "grid",
                format!(
                    "{} parameters: one or two (`{{name: points, ...}}`)",
                    s.grid.len()
                ),
            ));
        }
        for (p, &n) in &s.grid {
            let field = format!("grid.{p}");
            if *p == s.speed {
                return Err(self.err(&field, "the speed is swept, not a grid parameter".into()));
            }
            swept(&field, p)?;
            points(&field, n, 2)?;
        }
        self.check_index("index", &s.index)?;
        if !(1..=MAX_CRITICAL_SPEED_EXCITATIONS).contains(&s.excitations) {
            return Err(self.err(
                "excitations",
                format!(
                    "{}: allowed 1 to {MAX_CRITICAL_SPEED_EXCITATIONS}",
                    s.excitations
                ),
            ));
        }
        let cells: usize = s.grid.values().product();
        if solver_check > cells {
            return Err(self.err(
                "solver_check",
                format!("{solver_check} is more than the grid's {cells} points"),
            ));
        }
        Ok(StudyKind::CriticalSpeed(CriticalSpeed {
            speed: s.speed,
            speeds: s.speeds,
            grid: s.grid.into_iter().collect(),
            index: s.index,
            excitations: s.excitations,
        }))
    }
}

/// The optimisation's own fields, checked (the index names are checked by the caller).
fn parse_optimise(
    s: OptimiseSpec,
    err: &dyn Fn(&str, String) -> SpecError,
) -> Result<Optimise, SpecError> {
    let objective: Vec<(String, f64)> = match &s.objective {
        Value::String(i) => vec![(i.clone(), 1.0)],
        Value::Object(terms) if !terms.is_empty() => terms
            .iter()
            .map(|(i, w)| match w.as_f64() {
                Some(w) if w.is_finite() && w != 0.0 => Ok((i.clone(), w)),
                _ => Err(err(
                    &format!("objective.{i}"),
                    format!("{w}: a finite, nonzero weight"),
                )),
            })
            .collect::<Result<_, _>>()?,
        v => {
            return Err(err(
                "objective",
                format!("{v}: an index name, or a mapping from index names to weights"),
            ))
        }
    };
    let maximise = match s.sense.as_str() {
        "minimise" => false,
        "maximise" => true,
        other => return Err(err("sense", format!("`{other}`: `minimise` or `maximise`"))),
    };
    let statistic = match &s.statistic {
        Value::String(m) if m == "mean" => Robust::Mean,
        Value::Object(q) if q.len() == 1 && q.contains_key("quantile") => {
            match q["quantile"].as_f64() {
                Some(p) if p > 0.0 && p < 1.0 => Robust::Quantile(p),
                _ => {
                    return Err(err(
                        "statistic.quantile",
                        format!("{}: a level in (0, 1)", q["quantile"]),
                    ))
                }
            }
        }
        v => {
            return Err(err(
                "statistic",
                format!("{v}: `mean` or `{{quantile: p}}` with p in (0, 1)"),
            ))
        }
    };
    if !(1..=MAX_OPTIMISE_EXCITATIONS).contains(&s.excitations) {
        return Err(err(
            "excitations",
            format!("{}: allowed 1 to {MAX_OPTIMISE_EXCITATIONS}", s.excitations),
        ));
    }
    if !(1..=MAX_OPTIMISE_STARTS).contains(&s.starts) {
        return Err(err(
            "starts",
            format!("{}: allowed 1 to {MAX_OPTIMISE_STARTS}", s.starts),
        ));
    }
    if !(1..=MAX_OPTIMISE_ITERATIONS).contains(&s.iterations) {
        return Err(err(
            "iterations",
            format!("{}: allowed 1 to {MAX_OPTIMISE_ITERATIONS}", s.iterations),
        ));
    }
    if s.runners_up >= s.starts {
        return Err(err(
            "runners_up",
            format!(
                "{}: fewer than the {} starts (a runner-up is the best point of another start)",
                s.runners_up, s.starts
            ),
        ));
    }
    Ok(Optimise {
        objective,
        maximise,
        limits: s.limits,
        excitations: s.excitations,
        statistic,
        starts: s.starts,
        iterations: s.iterations,
        runners_up: s.runners_up,
    })
}

fn parse_distribution(v: &Value, training: [f64; 2]) -> Result<Distribution, String> {
    if let Some(x) = v.as_f64() {
        return Ok(Distribution::Fixed(x));
    }
    let s: DistributionSpec = serde_json::from_value(v.clone()).map_err(|e| e.to_string())?;
    let [lo, hi] = s.range.unwrap_or(training);
    let given = [
        s.uniform.is_some(),
        s.normal.is_some(),
        s.lognormal.is_some(),
        s.fixed.is_some(),
    ];
    if given.iter().filter(|g| **g).count() != 1 {
        return Err("exactly one of uniform, normal, lognormal, fixed".into());
    }
    Ok(if let Some([lo, hi]) = s.uniform {
        Distribution::Uniform { lo, hi }
    } else if let Some(n) = s.normal {
        Distribution::Normal {
            mean: n.mean,
            std: n.std,
            lo,
            hi,
        }
    } else if let Some(l) = s.lognormal {
        Distribution::LogNormal {
            median: l.median,
            sigma_log: l.sigma_log,
            lo,
            hi,
        }
    } else {
        Distribution::Fixed(s.fixed.unwrap_or(f64::NAN))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn params() -> Vec<(String, [f64; 2])> {
        vec![("c_s".into(), [1.0, 2.0]), ("m_c".into(), [10.0, 20.0])]
    }

    #[test]
    fn a_monte_carlo_study_parses_with_defaults() {
        let s = Study::parse(
            &json!({"name": "wheel", "kind": "monte_carlo", "n": 100, "solver_check": 5,
                    "parameters": {"c_s": {"normal": {"mean": 1.5, "std": 0.2}}, "m_c": 12.0},
                    "limits": {"q": 0.6}}),
            &params(),
            &["q".into()],
        )
        .unwrap();
        assert_eq!(s.solver_check, 5);
        let d = s.distributions(&params());
        assert_eq!(
            d[0],
            Distribution::Normal {
                mean: 1.5,
                std: 0.2,
                lo: 1.0,
                hi: 2.0
            }
        );
        assert_eq!(d[1], Distribution::Fixed(12.0));
    }

    #[test]
    fn bad_declarations_name_the_field() {
        let idx = ["q".to_string()];
        let e = |v: Value| Study::parse(&v, &params(), &idx).unwrap_err().to_string();
        assert!(
            e(json!({"name": "a", "kind": "monte_carlo", "n": 10, "parameters": {"k": 1.0}}))
                .starts_with("study.a.parameters.k: not a sampled parameter")
        );
        assert!(
            e(json!({"name": "a", "kind": "monte_carlo", "n": 10, "limits": {"z": 1.0}}))
                .contains("`z` is not an index")
        );
        assert!(e(json!({"name": "a", "kind": "monte_carlo", "n": 0})).starts_with("study.a.n:"));
        assert!(
            e(json!({"name": "a", "kind": "monte_carlo", "n": 3, "solver_check": 4}))
                .starts_with("study.a.solver_check:")
        );
        assert!(e(json!({"name": "a", "kind": "mc", "n": 3})).starts_with("study.a.kind:"));
        assert!(
            e(json!({"name": "a", "kind": "monte_carlo", "n": 3, "m": 1}))
                .contains("unknown field `m`")
        );
        assert!(e(json!({"name": "a", "kind": "monte_carlo", "n": 3,
                         "parameters": {"c_s": {"normal": {"mean": 0.0, "std": -1.0}}}}))
        .contains("std"));
    }

    #[test]
    fn a_sensitivity_study_counts_its_factors_and_rows() {
        let idx = ["q".to_string()];
        let parse = |v: Value| Study::parse(&v, &params(), &idx);
        let s =
            parse(json!({"name": "s", "kind": "sensitivity", "n": 64, "solver_check": 8})).unwrap();
        assert_eq!(s.kind, StudyKind::Sensitivity { n: 64 });
        let e = |v: Value| parse(v).unwrap_err().to_string();
        assert!(e(json!({"name": "s", "kind": "sensitivity", "n": 48}))
            .starts_with("study.s.n: 48: a power of two"));
        assert!(e(json!({"name": "s", "kind": "sensitivity", "n": 2})).contains("from 4"));
        // Two varying parameters and the excitation: 5 evaluations per row.
        let most = (MAX_SENSITIVITY_EVALUATIONS / 5).min(pino_studies::sobol::MAX_ROWS);
        assert!(e(json!({"name": "s", "kind": "sensitivity", "n": 1 << 17}))
            .contains(&format!("to {most} rows")));
        assert!(
            e(json!({"name": "s", "kind": "sensitivity", "n": 64, "solver_check": 6}))
                .starts_with("study.s.solver_check: 6: 0 or a power of two")
        );
        assert!(
            e(json!({"name": "s", "kind": "sensitivity", "n": 64, "solver_check": 128}))
                .contains("more than the study's 64 rows")
        );
        assert!(e(json!({"name": "s", "kind": "sensitivity", "n": 64,
                         "parameters": {"c_s": 1.5, "m_c": 12.0}}))
        .starts_with("study.s.parameters: every parameter is fixed"));
    }

    #[test]
    fn an_optimisation_parses_its_goal_and_refuses_what_it_cannot_search() {
        let idx = ["q".to_string(), "r".to_string()];
        let parse = |v: Value| Study::parse(&v, &params(), &idx);
        let s = parse(
            json!({"name": "o", "kind": "optimise", "objective": {"q": 1.0, "r": 0.5},
                             "sense": "maximise", "statistic": {"quantile": 0.9},
                             "limits": {"r": 2.0}, "solver_check": 3,
                             "parameters": {"c_s": {"uniform": [1.2, 1.8]}, "m_c": 15.0}}),
        )
        .unwrap();
        let StudyKind::Optimise(o) = &s.kind else {
            panic!("not an optimisation: {:?}", s.kind)
        };
        assert_eq!(o.objective, vec![("q".into(), 1.0), ("r".into(), 0.5)]);
        assert!(o.maximise);
        assert_eq!(o.statistic, Robust::Quantile(0.9));
        assert_eq!(o.statistic.label(), "q90");
        assert_eq!((o.excitations, o.starts, o.runners_up), (8, 4, 2));
        assert_eq!(o.limits["r"], 2.0);
        let plain = parse(json!({"name": "o", "kind": "optimise", "objective": "q"})).unwrap();
        let StudyKind::Optimise(plain) = plain.kind else {
            panic!("not an optimisation")
        };
        assert_eq!(plain.objective, vec![("q".into(), 1.0)]);
        assert!(!plain.maximise);
        assert_eq!(plain.statistic, Robust::Mean);

        let e = |v: Value| parse(v).unwrap_err().to_string();
        let with = |extra: Value| {
            let mut v = json!({"name": "o", "kind": "optimise", "objective": "q"});
            v.as_object_mut()
                .unwrap()
                .extend(extra.as_object().unwrap().clone());
            e(v)
        };
        assert!(with(json!({"objective": "z"})).contains("`z` is not an index"));
        assert!(with(json!({"objective": {"q": 0.0}})).starts_with("study.o.objective.q:"));
        assert!(with(json!({"objective": 3})).starts_with("study.o.objective:"));
        assert!(with(json!({"sense": "down"})).starts_with("study.o.sense: `down`"));
        assert!(with(json!({"statistic": {"quantile": 1.5}}))
            .starts_with("study.o.statistic.quantile:"));
        assert!(with(json!({"statistic": "median"})).starts_with("study.o.statistic:"));
        assert!(with(json!({"excitations": 0})).starts_with("study.o.excitations: 0"));
        assert!(with(json!({"starts": 2, "runners_up": 2})).starts_with("study.o.runners_up:"));
        assert!(with(json!({"limits": {"z": 1.0}})).contains("`z` is not an index"));
        assert!(
            with(json!({"parameters": {"c_s": {"normal": {"mean": 1.5, "std": 0.1}}}}))
                .starts_with("study.o.parameters.c_s: an optimisation searches a box")
        );
        assert!(with(json!({"parameters": {"c_s": 1.5, "m_c": 12.0}}))
            .starts_with("study.o.parameters: every parameter is fixed"));
        assert!(with(json!({"solver_check": MAX_OPTIMISE_SOLVER_CHECK + 1}))
            .starts_with("study.o.solver_check:"));
    }

    #[test]
    fn a_critical_speed_study_sweeps_a_speed_over_a_grid_and_refuses_what_it_cannot_sweep() {
        let params = vec![
            ("v_kmh".to_string(), [300.0, 350.0]),
            ("gamma".into(), [0.05, 0.4]),
            ("c_yaw".into(), [1.5e5, 4.5e5]),
            ("m_c".into(), [3e4, 5e4]),
        ];
        let idx = [
            pino_indices::lateral::STABILITY_INDEX.to_string(),
            "q".into(),
        ];
        let s = Study::parse(
            &json!({"name": "cs", "kind": "critical_speed", "speed": "v_kmh",
                    "grid": {"gamma": 3, "c_yaw": 2}, "solver_check": 6,
                    "parameters": {"m_c": 4e4}}),
            &params,
            &idx,
        )
        .unwrap();
        let StudyKind::CriticalSpeed(c) = &s.kind else {
            panic!("{:?}", s.kind)
        };
        assert_eq!(c.speed, "v_kmh");
        assert_eq!((c.speeds, c.excitations), (11, 4));
        assert_eq!(c.index, pino_indices::lateral::STABILITY_INDEX);
        assert_eq!(c.grid, [("c_yaw".to_string(), 2), ("gamma".to_string(), 3)]);
        let e = |v: Value| Study::parse(&v, &params, &idx).unwrap_err().to_string();
        let base = |extra: Value| {
            let mut v = json!({"name": "cs", "kind": "critical_speed", "speed": "v_kmh",
                               "grid": {"gamma": 3}});
            for (k, x) in extra.as_object().unwrap() {
                v[k] = x.clone();
            }
            v
        };
        assert!(e(base(json!({"speed": "v"}))).starts_with("study.cs.speed: `v` is not a sampled"));
        assert!(
            e(base(json!({"grid": {"v_kmh": 3}}))).starts_with("study.cs.grid.v_kmh: the speed")
        );
        assert!(e(base(json!({"grid": {}}))).starts_with("study.cs.grid: 0 parameters"));
        assert!(e(base(json!({"grid": {"gamma": 2, "c_yaw": 2, "m_c": 2}})))
            .starts_with("study.cs.grid: 3 parameters"));
        assert!(
            e(base(json!({"grid": {"gamma": 1}}))).starts_with("study.cs.grid.gamma: 1: allowed 2")
        );
        assert!(e(base(json!({"speeds": 2}))).starts_with("study.cs.speeds: 2: allowed 3"));
        assert!(e(base(json!({"index": "z"}))).starts_with("study.cs.index: `z` is not an index"));
        assert!(e(base(json!({"excitations": 0}))).starts_with("study.cs.excitations: 0"));
        assert!(e(base(json!({"solver_check": 4})))
            .starts_with("study.cs.solver_check: 4 is more than the grid's 3 points"));
        assert!(e(base(json!({"parameters": {"gamma": 0.1}})))
            .starts_with("study.cs.grid.gamma: `gamma` is swept"));
        let no_range = vec![
            ("v_kmh".to_string(), [300.0, 300.0]),
            ("gamma".into(), [0.05, 0.4]),
        ];
        assert!(Study::parse(&base(json!({})), &no_range, &idx)
            .unwrap_err()
            .to_string()
            .starts_with("study.cs.speed: `v_kmh` has no finite training range"));
    }
}
