//! The explorer API's requests, parsed from JSON and validated before any work: a design (the
//! model's parameters by name; missing names take the nominal values), an excitation (a test
//! sample of the dataset or a generated profile from a seed) and the sweep's axis. Every refusal
//! is an [`ApiError`] naming the field and what is allowed, never a panic: the body is read as
//! untyped JSON first, so a wrong type, an unknown key, a non-number or an infinite value each
//! get their own message.

use serde::Serialize;
use serde_json::{Map, Value};

/// An error answer: the HTTP status and the JSON body `{error, field, allowed}`.
#[derive(Debug, Clone, PartialEq, Serialize, thiserror::Error)]
#[error("{error}")]
pub struct ApiError {
    /// HTTP status (400 bad input, 429 busy, 500 a fault of the server).
    #[serde(skip)]
    pub status: u16,
    /// What went wrong.
    pub error: String,
    /// The request field at fault (`design.k_pz`, `steps`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub field: Option<String>,
    /// What the field allows.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub allowed: Option<String>,
    /// For 429: seconds after which to retry.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub retry_after_s: Option<u64>,
}

impl ApiError {
    /// A 400 for `field`.
    pub fn bad(
        field: impl Into<String>,
        error: impl Into<String>,
        allowed: impl Into<String>,
    ) -> Self {
        Self {
            status: 400,
            error: error.into(),
            field: Some(field.into()),
            allowed: Some(allowed.into()),
            retry_after_s: None,
        }
    }

    /// A 429: the solver queue is full.
    pub fn busy(retry_after_s: u64) -> Self {
        Self {
            status: 429,
            error: "the solver is busy: too many solves running or queued".into(),
            field: None,
            allowed: None,
            retry_after_s: Some(retry_after_s),
        }
    }

    /// A 500: a fault of the server, not of the request.
    pub fn internal(error: impl std::fmt::Display) -> Self {
        Self {
            status: 500,
            error: error.to_string(),
            field: None,
            allowed: None,
            retry_after_s: None,
        }
    }

    /// The HTTP answer: the status, the JSON body and, for a 429, `Retry-After`.
    pub fn response(self) -> axum::response::Response {
        use axum::http::{header, HeaderValue, StatusCode};
        use axum::response::IntoResponse;
        let status = StatusCode::from_u16(self.status).unwrap_or(StatusCode::INTERNAL_SERVER_ERROR);
        let retry = self.retry_after_s;
        let mut r = (status, axum::Json(&self)).into_response();
        if let Some(s) = retry {
            r.headers_mut()
                .insert(header::RETRY_AFTER, HeaderValue::from(s));
        }
        r
    }
}

/// Where the profiles under the system come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum Excitation {
    /// The profile of a test sample of the dataset (the one its simulation used).
    Test {
        /// Its sample id.
        sample_id: i64,
    },
    /// Generated as the `irregularity` stage generates them, with the dataset's settings.
    Seed {
        /// Seed of the random phases.
        seed: u64,
        /// Sample id of the stream.
        id: u64,
    },
}

/// A design and its excitation (the body of predict, solve and the downloads).
#[derive(Debug, Clone, PartialEq)]
pub struct DesignRequest {
    /// Every parameter's value, in the model's order.
    pub design: Vec<f64>,
    /// The excitation; `None`: the model's default.
    pub excitation: Option<Excitation>,
    /// Coverage of the intervals (default [`DEFAULT_COVERAGE`]); ignored without a
    /// calibration.
    pub coverage: f64,
    /// The channels whose bands the answer carries (`None`: every banded channel).
    pub bands: Option<Vec<String>>,
    /// How the answer writes its curves.
    pub encoding: Encoding,
}

/// How an answer writes its curves (`encoding` of a request).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Encoding {
    /// Arrays of JSON numbers (every digit of the f64 values).
    #[default]
    Json,
    /// Each curve a base64 string of its values as little-endian float32 (7 significant
    /// digits, a fifth of the bytes), each band its half-width the same way.
    F32,
}

/// The coverage of the intervals when a request names none.
pub const DEFAULT_COVERAGE: f64 = pino_calibration::DEFAULT_COVERAGE;

/// Whether `n` calibration samples support `coverage` (in (0, 1)): the conformal rank
/// `ceil((n + 1) c)` is at most `n` ([`pino_calibration::conformal_rank`]); the refusal
/// says what is allowed.
pub fn coverage_supported(n: usize, coverage: f64) -> Result<(), String> {
    match pino_calibration::conformal_rank(n, coverage) {
        Ok(_) => Ok(()),
        Err(_) => Err(format!(
            "a level the calibration's {n} samples support: at most n / (n + 1) = {:.4}",
            pino_calibration::max_coverage(n)
        )),
    }
}

/// A one-parameter sweep.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepRequest {
    /// The base design and excitation.
    pub base: DesignRequest,
    /// Index of the swept parameter.
    pub parameter: usize,
    /// First and last value (inclusive).
    pub from: f64,
    /// Last value.
    pub to: f64,
    /// Number of designs.
    pub steps: usize,
    /// How many of them also go through the solver.
    pub solve_points: usize,
}

/// The kinds of study the sweep view starts (`docs/studies.md`): the optimisation needs an
/// objective and limits the view does not ask for, so it stays a pipeline declaration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum StartedKind {
    /// Exceedance probabilities and quantiles over the varied parameters.
    MonteCarlo,
    /// Sobol indices of the varied parameters and the excitation.
    Sensitivity,
}

impl StartedKind {
    /// The `kind` of the study's declaration.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::MonteCarlo => pino_study::spec::MONTE_CARLO,
            Self::Sensitivity => pino_study::spec::SENSITIVITY,
        }
    }

    /// Designs (rows) when a request names none: a Monte Carlo study of a few seconds, a
    /// sensitivity design of 64 rows.
    pub fn default_n(self) -> usize {
        match self {
            Self::MonteCarlo => 500,
            Self::Sensitivity => 64,
        }
    }
}

/// The most parameters a study started from the sweep view varies.
pub const STUDY_MAX_VARIED: usize = 2;

/// The most designs of a Monte Carlo study started from the sweep view (a minute or less of
/// the surrogate on a laptop; larger ones belong in the pipeline file).
pub const STUDY_MAX_MONTE_CARLO: usize = 5000;

/// The most rows of a sensitivity study started from the sweep view.
pub const STUDY_MAX_SENSITIVITY_ROWS: usize = 1024;

/// The most designs (rows, for a sensitivity study) of a started study the solver checks.
pub const STUDY_MAX_SOLVER_CHECK: usize = 32;

/// A study started from the sweep view: one or two parameters uniform over their intervals,
/// every other parameter fixed at the design's value, each design under its own excitation.
#[derive(Debug, Clone, PartialEq)]
pub struct StudyRequest {
    /// The design whose other parameters stay fixed.
    pub design: Vec<f64>,
    /// Coverage of the intervals.
    pub coverage: f64,
    /// Monte Carlo or sensitivity.
    pub kind: StartedKind,
    /// The varied parameters: (index, from, to) with from < to.
    pub varied: Vec<(usize, f64, f64)>,
    /// Designs (Monte Carlo) or rows of the Saltelli design (sensitivity).
    pub n: usize,
    /// Designs (rows) also through the solver.
    pub solver_check: usize,
}

/// What the parser needs to know of the model: parameter names, nominal values and training
/// ranges, and the request limits.
#[derive(Debug, Clone)]
pub struct RequestRules {
    /// Parameter names in value order.
    pub names: Vec<String>,
    /// Nominal values.
    pub nominal: Vec<f64>,
    /// Training range of each parameter.
    pub ranges: Vec<[f64; 2]>,
    /// Most designs in one sweep.
    pub sweep_max_designs: usize,
    /// Most solver points in one sweep.
    pub sweep_max_solve_points: usize,
    /// Calibration samples of the model's calibration, when its answers carry intervals
    /// (`None`: a `coverage` in (0, 1) is accepted and no interval is computed).
    pub calibration_n: Option<usize>,
    /// The channels with a band (a request's `bands` names some of them).
    pub band_channels: Vec<String>,
}

fn object<'a>(v: &'a Value, field: &str) -> Result<&'a Map<String, Value>, ApiError> {
    v.as_object().ok_or_else(|| {
        ApiError::bad(
            field,
            format!("`{field}` must be a JSON object"),
            "an object",
        )
    })
}

fn only_keys(obj: &Map<String, Value>, field: &str, keys: &[&str]) -> Result<(), ApiError> {
    match obj.keys().find(|k| !keys.contains(&k.as_str())) {
        Some(k) => {
            let at = if field.is_empty() {
                k.clone()
            } else {
                format!("{field}.{k}")
            };
            Err(ApiError::bad(
                at,
                format!("unknown field `{k}`"),
                format!("fields: {}", keys.join(", ")),
            ))
        }
        None => Ok(()),
    }
}

/// A finite number at `field`.
fn number(v: &Value, field: &str) -> Result<f64, ApiError> {
    match v.as_f64() {
        Some(x) if x.is_finite() => Ok(x),
        _ => Err(ApiError::bad(
            field,
            format!("`{field}` = {v} is not a finite number"),
            "a finite number",
        )),
    }
}

/// A non-negative integer at `field`, in `lo..=hi`.
fn integer(v: &Value, field: &str, lo: u64, hi: u64) -> Result<u64, ApiError> {
    match v.as_u64() {
        Some(x) if (lo..=hi).contains(&x) => Ok(x),
        _ => Err(ApiError::bad(
            field,
            format!("`{field}` = {v} is out of range"),
            format!("an integer in {lo}..={hi}"),
        )),
    }
}

/// The start of the message of a key given twice in one object.
const DUPLICATE_KEY: &str = "duplicate key";

/// A JSON value read strictly: an object naming a key twice is refused, where serde_json's
/// own `Value` keeps the last one silently.
struct Strict(Value);

impl<'de> serde::Deserialize<'de> for Strict {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_any(StrictVisitor).map(Strict)
    }
}

struct StrictVisitor;

impl<'de> serde::de::Visitor<'de> for StrictVisitor {
    type Value = Value;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a JSON value")
    }

    fn visit_bool<E>(self, v: bool) -> Result<Value, E> {
        Ok(Value::Bool(v))
    }

    fn visit_i64<E>(self, v: i64) -> Result<Value, E> {
        Ok(Value::from(v))
    }

    fn visit_u64<E>(self, v: u64) -> Result<Value, E> {
        Ok(Value::from(v))
    }

    fn visit_f64<E>(self, v: f64) -> Result<Value, E> {
        Ok(Value::from(v))
    }

    fn visit_str<E>(self, v: &str) -> Result<Value, E> {
        Ok(Value::from(v))
    }

    fn visit_unit<E>(self) -> Result<Value, E> {
        Ok(Value::Null)
    }

    fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> Result<Value, A::Error> {
        let mut out = Vec::new();
        while let Some(Strict(v)) = seq.next_element()? {
            out.push(v);
        }
        Ok(Value::Array(out))
    }

    fn visit_map<A: serde::de::MapAccess<'de>>(self, mut map: A) -> Result<Value, A::Error> {
        let mut out = Map::new();
        while let Some(key) = map.next_key::<String>()? {
            if out.contains_key(&key) {
                return Err(serde::de::Error::custom(format!("{DUPLICATE_KEY} `{key}`")));
            }
            let Strict(v) = map.next_value()?;
            out.insert(key, v);
        }
        Ok(Value::Object(out))
    }
}

/// Parses a request body as a JSON object; a key given twice in one object is refused.
pub fn body(bytes: &[u8]) -> Result<Value, ApiError> {
    let Strict(v) = serde_json::from_slice(bytes).map_err(|e| {
        if e.to_string().starts_with(DUPLICATE_KEY) {
            ApiError::bad(
                "body",
                format!("the body names a key twice: {e}"),
                "a JSON object with each key once",
            )
        } else {
            ApiError::bad(
                "body",
                format!("the body is not valid JSON: {e}"),
                "a JSON object",
            )
        }
    })?;
    object(&v, "body")?;
    Ok(v)
}

impl RequestRules {
    fn design(&self, v: Option<&Value>) -> Result<Vec<f64>, ApiError> {
        let mut design = self.nominal.clone();
        let Some(v) = v else {
            return Ok(design);
        };
        for (name, value) in object(v, "design")? {
            let field = format!("design.{name}");
            let Some(k) = self.names.iter().position(|n| n == name) else {
                return Err(ApiError::bad(
                    field,
                    format!("unknown parameter `{name}`"),
                    format!("parameters: {}", self.names.join(", ")),
                ));
            };
            design[k] = number(value, &field)?;
        }
        Ok(design)
    }

    fn excitation(&self, v: Option<&Value>) -> Result<Option<Excitation>, ApiError> {
        let Some(v) = v.filter(|v| !v.is_null()) else {
            return Ok(None);
        };
        let obj = object(v, "excitation")?;
        let kind = obj.get("kind").and_then(Value::as_str).unwrap_or("");
        match kind {
            "test" => {
                only_keys(obj, "excitation", &["kind", "sample_id"])?;
                let id = obj.get("sample_id").unwrap_or(&Value::Null);
                let id = integer(id, "excitation.sample_id", 0, i64::MAX as u64)?;
                Ok(Some(Excitation::Test {
                    sample_id: id as i64,
                }))
            }
            "seed" => {
                only_keys(obj, "excitation", &["kind", "seed", "id"])?;
                let get = |k: &str| {
                    integer(
                        obj.get(k).unwrap_or(&Value::from(0)),
                        &format!("excitation.{k}"),
                        0,
                        u64::MAX,
                    )
                };
                Ok(Some(Excitation::Seed {
                    seed: get("seed")?,
                    id: get("id")?,
                }))
            }
            other => Err(ApiError::bad(
                "excitation.kind",
                format!("unknown excitation kind `{other}`"),
                "\"test\" (with sample_id) or \"seed\" (with seed, id)",
            )),
        }
    }

    /// The coverage of the intervals: a number in (0, 1) the calibration supports; absent,
    /// [`DEFAULT_COVERAGE`], or the highest level a calibration of fewer than 9 samples
    /// supports (`n / (n + 1)`).
    fn coverage(&self, v: Option<&Value>) -> Result<f64, ApiError> {
        let Some(v) = v.filter(|v| !v.is_null()) else {
            return Ok(match self.calibration_n {
                Some(n) if n > 0 && coverage_supported(n, DEFAULT_COVERAGE).is_err() => {
                    pino_calibration::max_coverage(n)
                }
                _ => DEFAULT_COVERAGE,
            });
        };
        let c = number(v, "coverage")?;
        if !(c > 0.0 && c < 1.0) {
            return Err(ApiError::bad(
                "coverage",
                format!("`coverage` = {c} is not a level in (0, 1)"),
                "a level in (0, 1), such as 0.8, 0.9 or 0.95",
            ));
        }
        if let Some(n) = self.calibration_n {
            coverage_supported(n, c).map_err(|allowed| {
                ApiError::bad(
                    "coverage",
                    format!(
                        "`coverage` = {c} is above what the model's calibration supports ({n} calibration samples)"
                    ),
                    allowed,
                )
            })?;
        }
        Ok(c)
    }

    /// The channels whose bands to answer: absent or `true` every one, `false` or `[]` none,
    /// or a list of channel names with a band.
    fn bands(&self, v: Option<&Value>) -> Result<Option<Vec<String>>, ApiError> {
        let allowed = || {
            format!(
                "true, false, or a list of channels with a band: {}",
                if self.band_channels.is_empty() {
                    "none (the model has no calibration)".to_owned()
                } else {
                    self.band_channels.join(", ")
                }
            )
        };
        match v {
            None | Some(Value::Null) | Some(Value::Bool(true)) => Ok(None),
            Some(Value::Bool(false)) => Ok(Some(Vec::new())),
            Some(Value::Array(names)) => names
                .iter()
                .map(|n| match n.as_str() {
                    Some(name) if self.band_channels.iter().any(|c| c == name) => {
                        Ok(name.to_owned())
                    }
                    _ => Err(ApiError::bad(
                        "bands",
                        format!("`bands`: {n} is not a channel with a band"),
                        allowed(),
                    )),
                })
                .collect::<Result<Vec<_>, _>>()
                .map(Some),
            Some(other) => Err(ApiError::bad(
                "bands",
                format!("`bands` = {other} is neither a boolean nor a list of channels"),
                allowed(),
            )),
        }
    }

    fn base(&self, obj: &Map<String, Value>) -> Result<DesignRequest, ApiError> {
        Ok(DesignRequest {
            design: self.design(obj.get("design"))?,
            excitation: self.excitation(obj.get("excitation"))?,
            coverage: self.coverage(obj.get("coverage"))?,
            bands: self.bands(obj.get("bands"))?,
            encoding: Encoding::Json,
        })
    }

    /// A design request: `{design, excitation, coverage, bands, encoding}` (`encoding`:
    /// `"json"`, the default, or `"f32"`).
    pub fn design_request(&self, v: &Value) -> Result<DesignRequest, ApiError> {
        let obj = object(v, "body")?;
        only_keys(
            obj,
            "",
            &["design", "excitation", "coverage", "bands", "encoding"],
        )?;
        let encoding = match obj.get("encoding") {
            None | Some(Value::Null) => Encoding::Json,
            Some(Value::String(e)) if e == "json" => Encoding::Json,
            Some(Value::String(e)) if e == "f32" => Encoding::F32,
            Some(other) => {
                return Err(ApiError::bad(
                    "encoding",
                    format!("`encoding` = {other} is not an encoding of curves"),
                    "\"json\" (arrays of numbers) or \"f32\" (base64 float32 arrays)",
                ))
            }
        };
        Ok(DesignRequest {
            encoding,
            ..self.base(obj)?
        })
    }

    /// A sweep request: `{design, excitation, coverage, parameter, from, to, steps,
    /// solve_points}`.
    pub fn sweep_request(&self, v: &Value) -> Result<SweepRequest, ApiError> {
        let obj = object(v, "body")?;
        only_keys(
            obj,
            "",
            &[
                "design",
                "excitation",
                "coverage",
                "bands",
                "parameter",
                "from",
                "to",
                "steps",
                "solve_points",
            ],
        )?;
        let base = self.base(obj)?;
        let allowed = format!("one of {}", self.names.join(", "));
        let name = obj
            .get("parameter")
            .and_then(Value::as_str)
            .ok_or_else(|| {
                ApiError::bad(
                    "parameter",
                    "`parameter` (the swept parameter's name) is missing",
                    allowed.clone(),
                )
            })?;
        let parameter = self.names.iter().position(|n| n == name).ok_or_else(|| {
            ApiError::bad("parameter", format!("unknown parameter `{name}`"), allowed)
        })?;
        let [lo, hi] = self.ranges[parameter];
        let end = |k: &str, default: f64| obj.get(k).map_or(Ok(default), |v| number(v, k));
        let steps = obj.get("steps").map_or(Ok(100), |v| {
            integer(v, "steps", 2, self.sweep_max_designs as u64)
        })? as usize;
        let solve_points = obj.get("solve_points").map_or(Ok(0), |v| {
            integer(
                v,
                "solve_points",
                0,
                self.sweep_max_solve_points.min(steps) as u64,
            )
        })? as usize;
        Ok(SweepRequest {
            base,
            parameter,
            from: end("from", lo)?,
            to: end("to", hi)?,
            steps,
            solve_points,
        })
    }
}

impl RequestRules {
    /// A study request: `{design, coverage, kind, parameters: [{name, from, to}], n,
    /// solver_check}`. The study's own rules (a power of two for a sensitivity design, ...)
    /// are checked again by the study's declaration parser.
    pub fn study_request(&self, v: &Value) -> Result<StudyRequest, ApiError> {
        let obj = object(v, "body")?;
        only_keys(
            obj,
            "",
            &[
                "design",
                "coverage",
                "kind",
                "parameters",
                "n",
                "solver_check",
            ],
        )?;
        let kind = study_kind(obj)?;
        let varied = self.varied(obj)?;
        let max_n = match kind {
            StartedKind::MonteCarlo => STUDY_MAX_MONTE_CARLO,
            StartedKind::Sensitivity => STUDY_MAX_SENSITIVITY_ROWS,
        };
        const MIN_ROWS: usize = pino_study::spec::MIN_SENSITIVITY_ROWS;
        let n = obj.get("n").map_or(Ok(kind.default_n() as u64), |v| {
            integer(v, "n", 1, max_n as u64)
        })? as usize;
        if kind == StartedKind::Sensitivity && !(n >= MIN_ROWS && n.is_power_of_two()) {
            return Err(ApiError::bad(
                "n",
                format!("`n` = {n} rows is not a power of two from {MIN_ROWS} to {max_n}"),
                format!("a power of two from {MIN_ROWS} to {max_n}"),
            ));
        }
        let solver_check = obj.get("solver_check").map_or(Ok(0), |v| {
            integer(v, "solver_check", 0, STUDY_MAX_SOLVER_CHECK.min(n) as u64)
        })? as usize;
        Ok(StudyRequest {
            design: self.design(obj.get("design"))?,
            coverage: self.coverage(obj.get("coverage"))?,
            kind,
            varied,
            n,
            solver_check,
        })
    }

    /// The varied parameters of a study request: `parameters: [{name, from, to}]`, each
    /// known, listed once, with `from < to` (the training range by default).
    fn varied(&self, obj: &Map<String, Value>) -> Result<Vec<(usize, f64, f64)>, ApiError> {
        let list = obj
            .get("parameters")
            .and_then(Value::as_array)
            .filter(|l| (1..=STUDY_MAX_VARIED).contains(&l.len()))
            .ok_or_else(|| {
                ApiError::bad(
                    "parameters",
                    "`parameters` must list the varied parameters",
                    format!("a list of 1 to {STUDY_MAX_VARIED} objects {{name, from, to}}"),
                )
            })?;
        let mut varied = Vec::new();
        for (i, p) in list.iter().enumerate() {
            let at = format!("parameters[{i}]");
            let p = object(p, &at)?;
            only_keys(p, &at, &["name", "from", "to"])?;
            let allowed = format!("one of {}", self.names.join(", "));
            let name = p.get("name").and_then(Value::as_str).unwrap_or("");
            let k = self.names.iter().position(|n| n == name).ok_or_else(|| {
                ApiError::bad(
                    format!("{at}.name"),
                    format!("unknown parameter `{name}`"),
                    allowed,
                )
            })?;
            if varied.iter().any(|&(j, _, _)| j == k) {
                return Err(ApiError::bad(
                    format!("{at}.name"),
                    format!("`{name}` is listed twice"),
                    "distinct parameters",
                ));
            }
            let [lo, hi] = self.ranges[k];
            let end = |key: &str, default: f64| {
                p.get(key)
                    .map_or(Ok(default), |v| number(v, &format!("{at}.{key}")))
            };
            let (from, to) = (end("from", lo)?, end("to", hi)?);
            if from >= to {
                return Err(ApiError::bad(
                    format!("{at}.to"),
                    format!("`{at}`: from = {from} is not below to = {to}"),
                    "an interval with from < to",
                ));
            }
            varied.push((k, from, to));
        }
        Ok(varied)
    }
}

/// The study a cancel request names: `{"name": NAME}`.
pub fn cancel_request(v: &Value) -> Result<String, ApiError> {
    let obj = object(v, "body")?;
    only_keys(obj, "", &["name"])?;
    obj.get("name")
        .and_then(Value::as_str)
        .map(str::to_owned)
        .ok_or_else(|| {
            ApiError::bad(
                "name",
                "`name` (the running study's name) is missing",
                "the name of a running study of the Studies page",
            )
        })
}

/// The `kind` of a study request: one the sweep view starts.
fn study_kind(obj: &Map<String, Value>) -> Result<StartedKind, ApiError> {
    let known = [StartedKind::MonteCarlo, StartedKind::Sensitivity];
    let kinds = || {
        let names: Vec<String> = known
            .iter()
            .map(|k| format!("\"{}\"", k.as_str()))
            .collect();
        format!(
            "{} (an optimisation is declared in the pipeline file)",
            names.join(" or ")
        )
    };
    match obj.get("kind").and_then(Value::as_str) {
        Some(name) => known
            .into_iter()
            .find(|k| k.as_str() == name)
            .ok_or_else(|| ApiError::bad("kind", format!("unknown study kind `{name}`"), kinds())),
        None => Err(ApiError::bad("kind", "`kind` is missing", kinds())),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn rules() -> RequestRules {
        RequestRules {
            names: vec!["k".into(), "c".into()],
            nominal: vec![1.0, 2.0],
            ranges: vec![[0.5, 2.0], [1.0, 3.0]],
            sweep_max_designs: 400,
            sweep_max_solve_points: 8,
            calibration_n: None,
            band_channels: vec!["x".into()],
        }
    }

    fn refused(v: Value) -> ApiError {
        rules().design_request(&v).unwrap_err()
    }

    #[test]
    fn missing_parameters_take_nominal_values_and_outside_values_are_accepted() {
        let r = rules()
            .design_request(&json!({"design": {"c": 9.5}}))
            .unwrap();
        assert_eq!(r.design, vec![1.0, 9.5]);
        assert_eq!(r.excitation, None);
        let r = rules()
            .design_request(&json!({"excitation": {"kind": "seed", "seed": 3, "id": 4}}))
            .unwrap();
        assert_eq!(r.excitation, Some(Excitation::Seed { seed: 3, id: 4 }));
    }

    #[test]
    fn each_bad_field_is_named_with_what_it_allows() {
        let e = refused(json!({"design": {"m": 1.0}}));
        assert_eq!((e.status, e.field.as_deref()), (400, Some("design.m")));
        assert!(e.allowed.unwrap().contains("k, c"));
        let e = refused(json!({"design": {"k": "NaN"}}));
        assert_eq!(e.field.as_deref(), Some("design.k"));
        assert_eq!(e.allowed.as_deref(), Some("a finite number"));
        let e = refused(json!({"design": [1, 2]}));
        assert_eq!(e.field.as_deref(), Some("design"));
        let e = refused(json!({"design": {}, "colour": 1}));
        assert_eq!(e.field.as_deref(), Some("colour"));
        let e = refused(json!({"excitation": {"kind": "test", "sample_id": -1}}));
        assert_eq!(e.field.as_deref(), Some("excitation.sample_id"));
        let e = refused(json!({"excitation": {"kind": "wind"}}));
        assert_eq!(e.field.as_deref(), Some("excitation.kind"));
        // JSON has no NaN or infinity: such bodies are malformed.
        // A key twice, at any depth: refused, never the last one taken.
        for text in [
            "{\"design\": {\"k\": 1.0}, \"design\": {\"k\": 2.0}}",
            "{\"design\": {\"k\": 1.0, \"k\": 2.0}}",
            "{\"excitation\": [{\"kind\": \"seed\", \"kind\": \"test\"}]}",
        ] {
            let e = body(text.as_bytes()).unwrap_err();
            assert_eq!(e.field.as_deref(), Some("body"), "{text}");
            assert!(
                e.error.contains("twice") && e.error.contains('`'),
                "{text}: {e:?}"
            );
        }
        assert_eq!(
            body(b"{\"a\": [1, {\"b\": null}], \"c\": \"x\"}").unwrap(),
            json!({"a": [1, {"b": null}], "c": "x"})
        );
        for text in [
            "{\"design\": {\"k\": NaN}}",
            "{\"design\": {\"k\": 1e999}}",
            "{",
            "[]",
        ] {
            let e = body(text.as_bytes()).unwrap_err();
            assert_eq!(
                (e.status, e.field.as_deref()),
                (400, Some("body")),
                "{text}"
            );
        }
    }

    #[test]
    fn the_coverage_is_a_level_in_0_1_that_the_calibration_supports() {
        let r = rules().design_request(&json!({})).unwrap();
        assert_eq!(r.coverage, DEFAULT_COVERAGE);
        let r = rules().design_request(&json!({"coverage": 0.95})).unwrap();
        assert_eq!(r.coverage, 0.95);
        for bad in [json!(0.0), json!(1.0), json!(-0.5), json!(2), json!("0.9")] {
            let e = refused(json!({ "coverage": bad }));
            assert_eq!(
                (e.status, e.field.as_deref()),
                (400, Some("coverage")),
                "{bad}"
            );
        }
        // With 10 calibration samples: up to 10/11.
        let with = RequestRules {
            calibration_n: Some(10),
            ..rules()
        };
        for ok in [0.8, 0.9, 10.0 / 11.0] {
            assert!(
                with.design_request(&json!({ "coverage": ok })).is_ok(),
                "{ok}"
            );
        }
        let e = with
            .sweep_request(&json!({"parameter": "c", "coverage": 0.95}))
            .unwrap_err();
        assert_eq!(e.field.as_deref(), Some("coverage"));
        assert!(e.allowed.unwrap().contains("0.9091"));
        assert!(coverage_supported(19, 0.95).is_ok());
        // A calibration too small for the default: its highest level.
        let small = RequestRules {
            calibration_n: Some(3),
            ..rules()
        };
        assert_eq!(small.design_request(&json!({})).unwrap().coverage, 0.75);
        // The bands asked for: all by default, none, or some channels with a band.
        let bands = |v: Value| rules().design_request(&json!({ "bands": v }));
        assert_eq!(rules().design_request(&json!({})).unwrap().bands, None);
        assert_eq!(bands(json!(false)).unwrap().bands, Some(vec![]));
        assert_eq!(bands(json!(["x"])).unwrap().bands, Some(vec!["x".into()]));
        for bad in [json!(["y"]), json!("x"), json!([1])] {
            assert_eq!(bands(bad).unwrap_err().field.as_deref(), Some("bands"));
        }
        assert!(coverage_supported(0, 0.5).is_err());
    }

    #[test]
    fn sweeps_default_to_the_training_range_and_are_bounded() {
        let s = rules().sweep_request(&json!({"parameter": "c"})).unwrap();
        assert_eq!((s.parameter, s.from, s.to, s.steps), (1, 1.0, 3.0, 100));
        let e = rules()
            .sweep_request(&json!({"parameter": "c", "steps": 100000}))
            .unwrap_err();
        assert_eq!(e.field.as_deref(), Some("steps"));
        assert_eq!(e.allowed.as_deref(), Some("an integer in 2..=400"));
        let e = rules()
            .sweep_request(&json!({"parameter": "c", "steps": 4, "solve_points": 5}))
            .unwrap_err();
        assert_eq!(e.field.as_deref(), Some("solve_points"));
        let e = rules()
            .sweep_request(&json!({"parameter": "x"}))
            .unwrap_err();
        assert_eq!(e.field.as_deref(), Some("parameter"));
    }
}
