//! The files of a critical-speed study: the critical speed of every grid point by each side
//! (`critical_speed.{parquet,csv}`: the grid parameters, `source`, `state`, the speed and,
//! for the calibrated surrogate, its band), every sweep's mean growth (`sweep.parquet`: grid
//! point, speed, `source`, the mean growth and its intervals' means), every run's growth
//! (`evaluations.parquet`: with its excitation id), the summary and the timings
//! ([`SPEED_FILE`](super::SPEED_FILE)).

use super::{finish, num, study_units, CRITICAL_SPEED_TABLE_FILE, EXCITATION, SOLVER_FAILURE};
use crate::critical_speed::{CriticalSpeedStudy, Crossing, Sweeps};
use crate::source;
use crate::spec::Study;
use crate::Result;
use pino_data::units::{Units, DIMENSIONLESS};
use pino_data::{Column, Table};
use pino_predict::Predictor;
use std::path::Path;

/// Column of a grid point's number.
pub const CELL: &str = "cell";
/// Column of the critical speed (the speed parameter's unit; NaN unless `state` is
/// `crossing`).
pub const CRITICAL: &str = "critical_speed";
/// Column of where the crossing lies: `below`, `crossing`, `above` or `unknown`.
pub const STATE: &str = "state";
/// Column of the growth (the index's unit).
pub const GROWTH: &str = "growth";

/// Writes a critical-speed study's files into `out`.
pub fn write_critical_speed(
    out: &Path,
    predictor: &Predictor,
    study: &Study,
    r: &CriticalSpeedStudy,
) -> Result<()> {
    let speed_unit = predictor
        .units()?
        .unit(&r.spec.speed)
        .unwrap_or(DIMENSIONLESS)
        .to_owned();
    let index_unit = predictor
        .index_inputs()
        .columns()
        .iter()
        .find(|c| c.name == r.spec.index)
        .map_or(DIMENSIONLESS.to_owned(), |c| c.unit.clone());
    let mut extra: Vec<(String, &str)> =
        vec![(CELL.into(), DIMENSIONLESS), (STATE.into(), DIMENSIONLESS)];
    for s in ["", "_lo", "_hi"] {
        extra.push((format!("{CRITICAL}{s}"), speed_unit.as_str()));
        extra.push((format!("{GROWTH}{s}"), index_unit.as_str()));
    }
    let extra: Vec<(&str, &str)> = extra.iter().map(|(n, u)| (n.as_str(), *u)).collect();
    let units = study_units(predictor, &extra)?;
    let critical = critical_table(&units, r)?;
    pino_data::write_parquet(&out.join("critical_speed.parquet"), &critical)?;
    report::csv::write_csv(&out.join(CRITICAL_SPEED_TABLE_FILE), &critical)
        .map_err(super::report_err)?;
    pino_data::write_parquet(&out.join("sweep.parquet"), &sweep_table(&units, r)?)?;
    pino_data::write_parquet(
        &out.join("evaluations.parquet"),
        &evaluations_table(&units, r)?,
    )?;
    finish(
        out,
        (r.surrogate_runs(), r.surrogate_s),
        (r.solver_runs(), r.solver_s),
        &summary_markdown(study, r, &speed_unit),
    )
}

/// The two sides of a study in the tables' order: the surrogate's sweeps, then the solver's.
fn sides(r: &CriticalSpeedStudy) -> [(&'static str, &Sweeps); 2] {
    [
        (source::SURROGATE, &r.surrogate),
        (source::SOLVER, &r.solver),
    ]
}

/// The grid parameters' columns of `cells`.
fn push_grid(t: &mut Table, r: &CriticalSpeedStudy, cells: &[usize]) -> Result<()> {
    t.push(CELL, Column::I64(cells.iter().map(|&c| c as i64).collect()))?;
    for (j, (name, _)) in r.spec.grid.iter().enumerate() {
        t.push(
            name,
            Column::F64(cells.iter().map(|&c| r.points[c][j]).collect()),
        )?;
    }
    Ok(())
}

/// One row per grid point and side: where its crossing lies, the speed and the band.
fn critical_table(units: &Units, r: &CriticalSpeedStudy) -> Result<Table> {
    let mut cells = Vec::new();
    let mut src = Vec::new();
    let mut crossings: Vec<Crossing> = Vec::new();
    let mut band: Vec<(f64, f64)> = Vec::new();
    let mut failures = Vec::new();
    for (name, sweeps) in sides(r) {
        let b = sweeps.critical_band(&r.speeds);
        for (k, c) in sweeps.critical(&r.speeds).into_iter().enumerate() {
            cells.push(sweeps.cells[k]);
            src.push(name.to_owned());
            crossings.push(c);
            band.push(
                b.as_ref()
                    .map_or((f64::NAN, f64::NAN), |b| (b[k].0.speed(), b[k].1.speed())),
            );
            failures.push(sweeps.failures[k].clone());
        }
    }
    let mut t = Table::default().with_units(units.clone());
    push_grid(&mut t, r, &cells)?;
    t.push("source", Column::Str(src))?;
    t.push(
        STATE,
        Column::Str(crossings.iter().map(|c| c.state().to_owned()).collect()),
    )?;
    t.push(
        CRITICAL,
        Column::F64(crossings.iter().map(|c| c.speed()).collect()),
    )?;
    t.push(
        &format!("{CRITICAL}_lo"),
        Column::F64(band.iter().map(|b| b.0).collect()),
    )?;
    t.push(
        &format!("{CRITICAL}_hi"),
        Column::F64(band.iter().map(|b| b.1).collect()),
    )?;
    t.push(SOLVER_FAILURE, Column::OptStr(failures))?;
    Ok(t)
}

/// One row per grid point, speed and side: the mean growth over the excitations and the
/// means of its intervals' ends (NaN without).
fn sweep_table(units: &Units, r: &CriticalSpeedStudy) -> Result<Table> {
    let mut cells = Vec::new();
    let mut speed = Vec::new();
    let mut src = Vec::new();
    let mut growth = [Vec::new(), Vec::new(), Vec::new()];
    for (name, sweeps) in sides(r) {
        let mean = sweeps.mean();
        let bounds = sweeps.mean_bounds();
        for (k, &c) in sweeps.cells.iter().enumerate() {
            for (s, &v) in r.speeds.iter().enumerate() {
                cells.push(c);
                speed.push(v);
                src.push(name.to_owned());
                growth[0].push(mean[k][s]);
                growth[1].push(bounds.as_ref().map_or(f64::NAN, |b| b.0[k][s]));
                growth[2].push(bounds.as_ref().map_or(f64::NAN, |b| b.1[k][s]));
            }
        }
    }
    let mut t = Table::default().with_units(units.clone());
    push_grid(&mut t, r, &cells)?;
    t.push(&r.spec.speed, Column::F64(speed))?;
    t.push("source", Column::Str(src))?;
    for (suffix, g) in ["", "_lo", "_hi"].iter().zip(growth) {
        t.push(&format!("{GROWTH}{suffix}"), Column::F64(g))?;
    }
    Ok(t)
}

/// One row per run: grid point, speed, excitation id, side and its growth.
fn evaluations_table(units: &Units, r: &CriticalSpeedStudy) -> Result<Table> {
    let mut cells = Vec::new();
    let mut speed = Vec::new();
    let mut excitation = Vec::new();
    let mut src = Vec::new();
    let mut growth = Vec::new();
    for (name, sweeps) in sides(r) {
        for (k, &c) in sweeps.cells.iter().enumerate() {
            for (s, &v) in r.speeds.iter().enumerate() {
                for (e, &g) in sweeps.growth[k][s].iter().enumerate() {
                    cells.push(c);
                    speed.push(v);
                    excitation.push(e as i64);
                    src.push(name.to_owned());
                    growth.push(g);
                }
            }
        }
    }
    let mut t = Table::default().with_units(units.clone());
    push_grid(&mut t, r, &cells)?;
    t.push(&r.spec.speed, Column::F64(speed))?;
    t.push(EXCITATION, Column::I64(excitation))?;
    t.push("source", Column::Str(src))?;
    t.push(GROWTH, Column::F64(growth))?;
    Ok(t)
}

/// The study's report: what was swept, the critical speed per grid point by each side.
fn summary_markdown(study: &Study, r: &CriticalSpeedStudy, unit: &str) -> String {
    let s = &r.spec;
    let grid: Vec<String> = s
        .grid
        .iter()
        .map(|(p, n)| format!("`{p}` ({n} points)"))
        .collect();
    let mut md = format!(
        "# Critical speed: `{}`\n\nThe speed `{}` swept over {:.4} to {:.4} {unit} at {} \
         points, at each point of the grid over {}; the growth index `{}` (mean over {} \
         tracks) turns positive at the critical speed (`below`: already at the lowest \
         speed; `above`: never within the sweep). The other parameters at their \
         distributions' medians. {} grid points also through the solver.\n\n",
        study.name,
        s.speed,
        r.speeds[0],
        r.speeds[r.speeds.len() - 1],
        s.speeds,
        grid.join(" x "),
        s.index,
        s.excitations,
        r.solver.cells.len(),
    );
    let names: Vec<&str> = s.grid.iter().map(|(p, _)| p.as_str()).collect();
    md.push_str(&format!(
        "| {} | surrogate ({unit}) | band ({unit}) | solver ({unit}) |\n|{}---|---|---|\n",
        names.join(" | "),
        "---|".repeat(names.len())
    ));
    let surrogate = r.surrogate.critical(&r.speeds);
    let band = r.surrogate.critical_band(&r.speeds);
    let solver = r.solver.critical(&r.speeds);
    let show = |c: Crossing| match c {
        Crossing::At(v) => num(v),
        other => other.state().to_owned(),
    };
    for (k, point) in r.points.iter().enumerate() {
        let values: Vec<String> = point.iter().map(|x| num(*x)).collect();
        let b = band.as_ref().map_or("-".to_owned(), |b| {
            format!("{} to {}", show(b[k].0), show(b[k].1))
        });
        let checked = r
            .solver
            .cells
            .iter()
            .position(|&c| c == k)
            .map_or("-".to_owned(), |i| show(solver[i]));
        md.push_str(&format!(
            "| {} | {} | {b} | {checked} |\n",
            values.join(" | "),
            show(surrogate[k])
        ));
    }
    md
}
