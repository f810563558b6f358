//! Validation and compilation: names resolved once (parameters, bodies, points, beams,
//! profiles, elements), every problem reported with its line, then the flat [`System`].
//!
//! Checks, beyond the shapes checked by [`crate::schema`]:
//! - every name an expression uses is a parameter; every parameter is used; derived
//!   parameters form no cycle (the cycle is named);
//! - counts (`modes`, `supports.count`) are integers fixed for every sample;
//! - element ends and load points name a body, one of its points, a moving point or `ground`;
//!   an element's upper end is a body; a profile sits under a moving point;
//! - every body DOF is restrained: the stiffness the elements give the rigid DOFs, with the
//!   beams and the ground held, is positive definite at the nominal values (else every DOF
//!   whose pivot vanishes is named);
//! - every field is in its domain at the nominal values (a mass > 0, a damping >= 0, ...);
//!   [`System::instantiate`] checks each sample again;
//! - every column name (the naming rule of `docs/systems.md`) is unique, and `outputs` and
//!   `indices` name columns that exist.
//!
//! [`compile`] runs one phase per section of the description, each a method of a small
//! compilation context (the description, the parameter scope that records which names are
//! used, the problems found), so the problems are found in the order of the sections.
//! The phases live by subject: `parameters` (derived order, values fixed for every sample),
//! `structure` (bodies, beams, moving points, sensors), `elements` (profiles, force
//! elements, loads), `columns` (the stored columns and the sections that name them) and
//! `assemble` (the flat force terms per DOF).

mod assemble;
mod columns;
mod elements;
mod parameters;
mod structure;

use assemble::assemble;
use columns::{channel_table, stored_channels};
use parameters::derived_order;

use crate::diag::Diagnostics;
use crate::expr::Expr;
use crate::reader::Field;
use crate::schema::{
    self, Axis, DofKind, Named, ParamKind, RawBeam, RawBody, RawCreep, RawDescription, RawElement,
    RawGeometry, RawLaw, RawLink, RawProfileKind, RawSupports, RawWheelset,
};
use crate::system::*;
use crate::yaml::Pos;
use std::collections::{BTreeMap, HashMap};

/// A value overriding a parameter of the description for one run (`system_values`).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(untagged)]
pub enum Override {
    /// A fixed parameter's value, or a sampled parameter's nominal value.
    Value(f64),
    /// A sampled parameter's range `[min, max]`.
    Range([f64; 2]),
}

struct Scope<'a> {
    names: HashMap<&'a str, usize>,
    used: Vec<bool>,
}

impl<'a> Scope<'a> {
    fn resolve(&mut self, f: &Field, what: &str, diag: &mut Diagnostics) -> Option<Expr> {
        let mut e = f.expr.clone();
        let names = &self.names;
        let resolved = e.resolve(&|n| names.get(n).copied());
        // The known names count as used even when another name is unknown (no follow-on
        // "never used" for them).
        self.mark_used(&f.expr);
        match resolved {
            Ok(()) => Some(e),
            Err(name) => {
                diag.push(
                    f.pos,
                    format!(
                        "{what}: unknown parameter `{name}`; parameters: {}",
                        self.known()
                    ),
                );
                None
            }
        }
    }

    fn mark_used(&mut self, e: &Expr) {
        for n in e.names() {
            if let Some(&i) = self.names.get(n) {
                self.used[i] = true;
            }
        }
    }

    /// The parameter names, sorted, for messages.
    fn known(&self) -> String {
        let mut known: Vec<&str> = self.names.keys().copied().collect();
        known.sort_unstable();
        known.join(", ")
    }

    fn opt(
        &mut self,
        f: &Option<Field>,
        default: f64,
        what: &str,
        diag: &mut Diagnostics,
    ) -> Option<Expr> {
        match f {
            Some(f) => self.resolve(f, what, diag),
            None => Some(Expr::Num(default)),
        }
    }

    fn req(&mut self, f: &Option<Field>, what: &str, diag: &mut Diagnostics) -> Option<Expr> {
        f.as_ref().and_then(|f| self.resolve(f, what, diag))
    }
}

/// An override of a run that the description's parameter table does not take: the
/// parameter's name and why (the caller says which argument the overrides came from: the
/// stages' `system_values`, the Python package's `values`).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{name}: {message}")]
pub struct OverrideError {
    /// The overridden name.
    pub name: String,
    /// Why the override is refused, with what is allowed.
    pub message: String,
}

/// Applies `overrides` to the parameter table (unknown names and derived parameters are
/// refused; the message names the allowed parameters).
pub fn apply_overrides(
    raw: &mut RawDescription,
    overrides: &BTreeMap<String, Override>,
) -> Result<(), OverrideError> {
    for (name, o) in overrides {
        let refuse = |message: String| OverrideError {
            name: name.clone(),
            message,
        };
        let Some(p) = raw.parameters.iter_mut().find(|p| &p.name == name) else {
            let known: Vec<&str> = raw.parameters.iter().map(|p| p.name.as_str()).collect();
            return Err(refuse(format!(
                "`{name}` is not a parameter of the description; parameters: {}",
                known.join(", ")
            )));
        };
        match (&mut p.kind, o) {
            (ParamKind::Fixed { value }, Override::Value(v)) if v.is_finite() => *value = *v,
            (ParamKind::Sampled { nominal, range }, Override::Value(v))
                if v.is_finite() && range[0] <= *v && *v <= range[1] =>
            {
                *nominal = *v
            }
            (ParamKind::Sampled { nominal, range }, Override::Range([lo, hi]))
                if lo.is_finite() && hi.is_finite() && lo < hi && *lo <= *nominal && *nominal <= *hi =>
            {
                *range = [*lo, *hi]
            }
            (ParamKind::Derived { .. }, _) => {
                return Err(refuse(format!(
                    "`{name}` is derived from other parameters; override those"
                )))
            }
            (ParamKind::Fixed { .. }, _) => {
                return Err(refuse("a fixed parameter takes a finite number".into()))
            }
            (ParamKind::Sampled { nominal, range }, _) => {
                return Err(refuse(format!(
                    "a sampled parameter takes a nominal value inside its range {range:?} or a range `[min, max]` containing the nominal {nominal}"
                )))
            }
        }
    }
    Ok(())
}

/// Validates and compiles a parsed description; every problem found goes to `diag`.
///
/// The phases run in the order of the description's sections, so the problems are found in
/// that order: the parameter table, bodies and their DOFs, beams, the moving frame, sensors,
/// profiles, elements, loads, the columns (`outputs`), `indices`, `railway`, `indices_from`, the
/// parameters never used; then, when nothing was found, the checks at the nominal values.
pub fn compile(raw: &RawDescription, diag: &mut Diagnostics) -> Option<System> {
    let mut cx = Compiler::new(raw, diag);
    let parameters = cx.parameters();
    let derived_order = derived_order(raw, &parameters, cx.diag);
    let (bodies, dofs) = cx.bodies();
    let beams = cx.beams(&parameters, &derived_order);
    let (points, speed) = cx.moving(&beams);
    let sensors = cx.sensors(&beams);
    let profiles = cx.profiles();
    let ends = Ends {
        bodies: &bodies,
        points: &points,
    };
    let elements = cx.elements(&ends, &profiles);
    let loads = cx.loads(&ends);
    cx.mark_derived_used(&parameters);
    let table = channel_table(&bodies, &dofs, &points, &sensors, &elements, raw, cx.diag);
    let channels = stored_channels(&dofs, &table, raw, cx.diag);
    let indices = cx.indices(&channels);
    let railway = cx.railway(&channels);
    let lateral = cx.lateral(&channels, &elements);
    let indices_from = cx.indices_from();
    cx.report_unused();
    let assembly = assemble(&bodies, &dofs, &elements, &loads);
    let sampled_list = parameters
        .iter()
        .filter(|p| matches!(p.source, ParamSource::Sampled { .. }))
        .map(|p| p.name.clone())
        .collect();
    let system = System {
        name: raw.name.clone(),
        doc: raw.doc.clone(),
        parameters,
        derived_order,
        bodies,
        dofs,
        beams,
        speed,
        points,
        sensors,
        profiles,
        elements,
        loads,
        assembly,
        channels,
        indices,
        railway,
        lateral,
        indices_from,
        sampled_list,
    };
    if !diag.is_empty() {
        return None;
    }
    crate::checks::nominal_checks(&system, raw, diag);
    diag.is_empty().then_some(system)
}

/// One compilation in progress: the description, its parameter scope (which names are used)
/// and the problems found so far.
struct Compiler<'a, 'd> {
    raw: &'a RawDescription,
    scope: Scope<'a>,
    diag: &'d mut Diagnostics,
}

/// What an end name can resolve to: the compiled bodies (with their points) and moving points.
struct Ends<'s> {
    bodies: &'s [Body],
    points: &'s [MovingPoint],
}

impl<'a, 'd> Compiler<'a, 'd> {
    /// The scope of the parameter names, each name checked (not reserved, not starting with
    /// a digit).
    fn new(raw: &'a RawDescription, diag: &'d mut Diagnostics) -> Self {
        let mut scope = Scope {
            names: HashMap::new(),
            used: vec![false; raw.parameters.len()],
        };
        for (i, p) in raw.parameters.iter().enumerate() {
            if crate::expr::is_reserved(&p.name) {
                diag.push(
                    p.pos,
                    format!(
                        "parameters.{}: `{}` is reserved (a constant or function of expressions)",
                        p.name, p.name
                    ),
                );
            }
            if p.name.starts_with(|c: char| c.is_ascii_digit()) {
                diag.push(
                    p.pos,
                    format!(
                        "parameters.{}: a parameter name starts with a letter or `_`",
                        p.name
                    ),
                );
            }
            scope.names.insert(&p.name, i);
        }
        Compiler { raw, scope, diag }
    }

    /// A required field, `fallback` where it is absent or fails (the system is refused then).
    fn req_or(&mut self, f: &Option<Field>, what: &str, fallback: f64) -> Expr {
        self.scope
            .req(f, what, self.diag)
            .unwrap_or(Expr::Num(fallback))
    }

    /// An optional field, `default` where it is absent or fails.
    fn opt_or(&mut self, f: &Option<Field>, default: f64, what: &str) -> Expr {
        self.scope
            .opt(f, default, what, self.diag)
            .unwrap_or(Expr::Num(default))
    }

    /// The parameter table: sampled, fixed and derived sources (a derived expression naming
    /// an unknown parameter becomes a NaN fixed value, its known names counted as used).
    fn parameters(&mut self) -> Vec<Parameter> {
        let mut parameters = Vec::with_capacity(self.raw.parameters.len());
        for p in &self.raw.parameters {
            let source = match &p.kind {
                ParamKind::Sampled { nominal, range } => ParamSource::Sampled {
                    nominal: *nominal,
                    range: *range,
                },
                ParamKind::Fixed { value } => ParamSource::Fixed(*value),
                ParamKind::Derived { expr } => {
                    let mut e = expr.expr.clone();
                    let names = &self.scope.names;
                    match e.resolve(&|n| names.get(n).copied()) {
                        Ok(()) => ParamSource::Derived(e),
                        Err(name) => {
                            self.diag.push(
                                expr.pos,
                                format!(
                                    "parameters.{}.expr: unknown parameter `{name}`; parameters: {}",
                                    p.name,
                                    self.scope.known()
                                ),
                            );
                            self.scope.mark_used(&expr.expr);
                            ParamSource::Fixed(f64::NAN)
                        }
                    }
                }
            };
            parameters.push(Parameter {
                name: p.name.clone(),
                unit: p.unit.clone(),
                doc: p.doc.clone(),
                source,
            });
        }
        parameters
    }

    /// Counts the parameters a derived parameter reads as used.
    fn mark_derived_used(&mut self, parameters: &[Parameter]) {
        for p in parameters {
            if let ParamSource::Derived(e) = &p.source {
                let mut ids = Vec::new();
                collect_ids(e, &mut ids);
                for j in ids {
                    self.scope.used[j] = true;
                }
            }
        }
    }

    /// Reports every parameter never used.
    fn report_unused(&mut self) {
        for (i, p) in self.raw.parameters.iter().enumerate() {
            if !self.scope.used[i] {
                self.diag.push(
                    p.pos,
                    format!(
                        "parameters.{}: declared but never used (remove it, or use it in a field)",
                        p.name
                    ),
                );
            }
        }
    }
}

/// Names for a message, `none` for none.
fn names<S: AsRef<str>>(it: impl Iterator<Item = S>) -> String {
    let v: Vec<String> = it.map(|s| s.as_ref().to_owned()).collect();
    if v.is_empty() {
        "none".to_owned()
    } else {
        v.join(", ")
    }
}

pub(crate) fn collect_ids(e: &Expr, out: &mut Vec<usize>) {
    match e {
        Expr::Num(_) => {}
        Expr::Var(_, id) => out.extend(*id),
        Expr::Neg(a) => collect_ids(a, out),
        Expr::Bin(_, a, b) => {
            collect_ids(a, out);
            collect_ids(b, out);
        }
        Expr::Call(_, args) => args.iter().for_each(|a| collect_ids(a, out)),
    }
}

/// Parses, validates and compiles a description text (`file` names it in messages), with
/// `overrides` applied to its parameter table (a refused override is reported as the
/// stages' `system_values.NAME`, at the top of the file).
pub fn load_str(
    text: &str,
    file: &str,
    overrides: &BTreeMap<String, Override>,
) -> Result<System, Diagnostics> {
    load_with_overrides(text, file, overrides).map_err(|e| match e {
        LoadError::Invalid(diag) => diag,
        LoadError::Override(o) => {
            let mut diag = Diagnostics {
                file: file.to_owned(),
                items: Vec::new(),
            };
            diag.push(Pos { line: 1, col: 1 }, format!("system_values.{o}"));
            diag
        }
    })
}

/// Why [`load_with_overrides`] refused: the description's problems, or an override the
/// description does not take (the text itself is fine).
#[derive(Debug)]
pub enum LoadError {
    /// The description's problems, each at its line.
    Invalid(Diagnostics),
    /// An override the parameter table refuses.
    Override(OverrideError),
}

/// [`load_str`], telling the description's own problems from a refused override.
pub fn load_with_overrides(
    text: &str,
    file: &str,
    overrides: &BTreeMap<String, Override>,
) -> Result<System, LoadError> {
    let mut diag = Diagnostics {
        file: file.to_owned(),
        items: Vec::new(),
    };
    let root = match crate::yaml::parse(text) {
        Ok(r) => r,
        Err(e) => {
            diag.push(e.pos, format!("not valid YAML: {}", e.message));
            return Err(LoadError::Invalid(diag));
        }
    };
    let mut raw = schema::read(&root, &mut diag);
    if !diag.is_empty() {
        return Err(LoadError::Invalid(diag));
    }
    apply_overrides(&mut raw, overrides).map_err(LoadError::Override)?;
    match compile(&raw, &mut diag) {
        Some(s) if diag.is_empty() => Ok(s),
        _ => Err(LoadError::Invalid(diag)),
    }
}
