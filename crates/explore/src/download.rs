//! The explorer's downloads, each carrying what reproduces it: the model's identity (its
//! directory and the blake3 of its files), the design and the excitation.
//!
//! - the design as YAML that `predict --params FILE` reads (`sets: [{name: value}]`; the
//!   `model:` and `excitation:` keys beside it are ignored by `predict`), with the command line
//!   in a comment;
//! - the predicted curves as CSV (`#` comment lines first, then `t` and every channel) or
//!   Parquet (the same columns with their units, and the provenance as the file's
//!   `pino.params` metadata, stage and unit `explore`).

use crate::request::{ApiError, DesignRequest};
use crate::session::{Explorer, Response};
use pino_data::{Column, Table};

/// The provenance of a download as JSON: model, design, excitation.
fn provenance(ex: &Explorer, req: &DesignRequest) -> serde_json::Value {
    serde_json::json!({
        "model": ex.identity(),
        "design": ex.design_map(&req.design),
        "excitation": ex.excitation_used(req.excitation),
    })
}

/// The design file.
pub fn design_yaml(ex: &Explorer, req: &DesignRequest) -> Result<String, ApiError> {
    let mut set = serde_yaml::Mapping::new();
    for (name, v) in ex.rules().names.iter().zip(&req.design) {
        set.insert(name.clone().into(), (*v).into());
    }
    let doc = serde_json::json!({
        "model": ex.identity(),
        "excitation": ex.excitation_used(req.excitation),
    });
    let mut head: serde_yaml::Mapping =
        serde_yaml::from_value(serde_yaml::to_value(&doc).map_err(ApiError::internal)?)
            .map_err(ApiError::internal)?;
    head.insert("sets".into(), serde_yaml::Value::Sequence(vec![set.into()]));
    let body = serde_yaml::to_string(&head).map_err(ApiError::internal)?;
    Ok(format!(
        "# A design from the pino-mbd explorer. Reproduce its prediction with:\n#   {}\n{body}",
        ex.predict_command(req.excitation, "design.yaml")
    ))
}

fn table(ex: &Explorer, r: &Response) -> Result<Table, ApiError> {
    let mut t = Table::default().with_units(ex.column_units().clone());
    t.push(pino_data::schema::TIME, Column::F64(r.t.clone()))
        .map_err(ApiError::internal)?;
    for (c, values) in ex.channels().iter().zip(&r.channels) {
        t.push(&c.name, Column::F64(values.clone()))
            .map_err(ApiError::internal)?;
    }
    Ok(t)
}

/// The curves as CSV text.
pub fn curves_csv(ex: &Explorer, req: &DesignRequest, r: &Response) -> Result<String, ApiError> {
    use std::fmt::Write;
    let mut out = format!("# pino-mbd explorer prediction: {}\n", provenance(ex, req));
    let names: Vec<&str> = std::iter::once(pino_data::schema::TIME)
        .chain(ex.channels().iter().map(|c| c.name.as_str()))
        .collect();
    out.push_str(&names.join(","));
    out.push('\n');
    for (n, t) in r.t.iter().enumerate() {
        let _ = write!(out, "{t}");
        for c in &r.channels {
            let _ = write!(out, ",{}", c[n]);
        }
        out.push('\n');
    }
    Ok(out)
}

/// The curves as Parquet bytes.
pub fn curves_parquet(
    ex: &Explorer,
    req: &DesignRequest,
    r: &Response,
) -> Result<Vec<u8>, ApiError> {
    let dir = tempfile::tempdir().map_err(ApiError::internal)?;
    let path = dir.path().join("curves.parquet");
    let origin = pino_data::metadata::Origin::stage_unit("explore", 0, 1, &provenance(ex, req));
    pino_data::write_parquet_from(&path, &table(ex, r)?, &origin).map_err(ApiError::internal)?;
    std::fs::read(&path).map_err(ApiError::internal)
}
