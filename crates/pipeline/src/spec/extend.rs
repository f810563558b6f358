//! `extends:`, a stage built on another of the same file.
//!
//! A stage that names `extends: BASE` starts as a copy of `BASE` as loaded, the `--set`s on
//! `BASE` applied: its command, `check`, inputs, shards, resources, matrix and parameters. Its
//! own fields then replace the copy's: `cmd`, `check`, `shards`, `resources` and `matrix`
//! whole, `inputs` and `params` key by key. A parameter it sets takes the key out of the
//! inherited matrix (`params: {algorithm: 5}` on a base with `matrix: {algorithm: [1, 2]}` is one
//! unit), and a key of its own matrix replaces the inherited parameter of that name. `--set` on the extending stage applies last, to inherited keys too. The base must not
//! itself extend another stage, so what a stage holds is at most one step from the file.
//!
//! The extending stage is an ordinary stage from then on: its identity is its resolved
//! command and parameters, so two stages that resolve alike differ only in name.

use super::{draft_stage, Draft, RawStage, SourceFile, UniqueMap, Upstreams};
use crate::Result;
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// The stage a `--set STAGE.KEY=VALUE` names (`""` when it names none).
pub(super) fn set_target(set: &str) -> &str {
    set.split_once('=')
        .map_or(set, |(lhs, _)| lhs)
        .split_once('.')
        .map_or("", |(stage, _)| stage)
}

/// Drafts the stage `name` that extends another (`rs.extends`) from that stage's draft in
/// `drafts` (which holds every stage that extends none).
pub(super) fn draft_extending(
    src: &SourceFile,
    workspace: &Path,
    base_dir: &Path,
    drafts: &BTreeMap<String, Draft>,
    extending: &BTreeSet<String>,
    name: String,
    rs: RawStage,
) -> Result<Draft> {
    let base_name = rs.extends.clone().unwrap_or_default();
    let line = src.loc.field_line(&name, "extends");
    let Some(base) = drafts.get(&base_name) else {
        let why = if extending.contains(&base_name) {
            format!("`{base_name}` extends another stage itself; extend that one")
        } else {
            let known: Vec<&str> = drafts.keys().chain(extending).map(String::as_str).collect();
            format!(
                "there is no stage `{base_name}` (stages: {})",
                known.join(", ")
            )
        };
        return Err(src.err(
            line,
            format!("stage `{name}`: extends `{base_name}`: {why}"),
        ));
    };
    let mut params = base.params.clone();
    let own_params = rs.params.map(|m| m.0).unwrap_or_default();
    // Its own matrix replaces the inherited parameters of its keys (one of its own parameters
    // of the same name is refused, as in any stage); an inherited matrix loses the keys it sets.
    let matrix = match rs.matrix {
        Some(m) => {
            params.retain(|k, _| !m.0.contains_key(k));
            m.0
        }
        None => {
            let mut m = base.matrix.clone();
            m.retain(|k, _| !own_params.contains_key(k));
            m
        }
    };
    params.extend(own_params);
    let mut inputs: BTreeMap<String, Upstreams> = base
        .stage
        .inputs
        .iter()
        .map(|(k, v)| (k.clone(), Upstreams::Many(v.clone())))
        .collect();
    inputs.extend(rs.inputs.map(|m| m.0).unwrap_or_default());
    let merged = RawStage {
        extends: None,
        cmd: Some(rs.cmd.unwrap_or_else(|| base.stage.cmd.clone())),
        params: Some(UniqueMap(params.into_iter().collect())),
        inputs: Some(UniqueMap(inputs)),
        shards: Some(rs.shards.unwrap_or(base.stage.shards)),
        matrix: Some(UniqueMap(matrix)),
        resources: Some(rs.resources.unwrap_or_else(|| base.stage.resources.clone())),
        check: Some(rs.check.unwrap_or(base.stage.check)),
    };
    let mut draft = draft_stage(src, workspace, base_dir, name, merged)?;
    draft.stage.overrides = base.stage.overrides.clone();
    draft.stage.extends = Some(base_name);
    Ok(draft)
}

#[cfg(test)]
mod tests {
    use crate::spec::tests::load;
    use crate::spec::Pipeline;

    fn params_of(p: &Pipeline, unit: &str) -> String {
        let e = p
            .stages
            .iter()
            .flat_map(|s| &s.expansions)
            .find(|e| e.name == unit)
            .unwrap_or_else(|| panic!("no unit {unit}"));
        serde_json::to_string(&e.params).unwrap()
    }

    const BASE: &str = "\
stages:
  data:
    cmd: [d]
  train:
    cmd: [t, sys.yaml]
    check: true
    inputs: {dataset: data}
    shards: 2
    matrix: {algorithm: [1, 2, 5]}
    params:
      epochs: 18
      width: 32
  train-rates:
    extends: train
    params:
      algorithm: 5
      rate_outputs: [z_a]
";

    #[test]
    fn an_extending_stage_inherits_what_it_does_not_replace() {
        let p = load(BASE, &[]).unwrap();
        let t = p.stage("train-rates").unwrap();
        assert_eq!(t.cmd, ["t", "sys.yaml"]);
        assert!(t.check);
        assert_eq!(t.shards, 2);
        assert_eq!(t.inputs["dataset"], ["data"]);
        assert_eq!(t.extends.as_deref(), Some("train"));
        // The parameter it sets takes the key out of the inherited matrix: one unit.
        let units: Vec<&str> = t.expansions.iter().map(|e| e.name.as_str()).collect();
        assert_eq!(units, ["train-rates"]);
        assert_eq!(
            params_of(&p, "train-rates"),
            r#"{"algorithm":5,"epochs":18,"rate_outputs":["z_a"],"width":32}"#
        );
        // The base is untouched.
        assert_eq!(p.stage("train").unwrap().expansions.len(), 3);
        assert_eq!(p.stage("train").unwrap().extends, None);
    }

    #[test]
    fn its_own_fields_replace_the_bases() {
        let text = BASE.replace(
            "    params:\n      algorithm: 5\n",
            "    cmd: [t2]\n    shards: 1\n    matrix: {algorithm: [4, 5]}\n    inputs: {extra: data}\n    params:\n      epochs: 3\n",
        );
        let p = load(&text, &[]).unwrap();
        let t = p.stage("train-rates").unwrap();
        assert_eq!(t.cmd, ["t2"]);
        assert_eq!(t.shards, 1);
        assert_eq!(t.inputs.len(), 2);
        let units: Vec<&str> = t.expansions.iter().map(|e| e.name.as_str()).collect();
        assert_eq!(
            units,
            ["train-rates[algorithm=4]", "train-rates[algorithm=5]"]
        );
        assert_eq!(
            params_of(&p, "train-rates[algorithm=4]"),
            r#"{"algorithm":4,"epochs":3,"rate_outputs":["z_a"],"width":32}"#
        );
        // A key of its own matrix replaces the inherited parameter of that name.
        let text = BASE.replace(
            "    params:\n      algorithm: 5\n",
            "    matrix: {width: [8, 16]}\n    params:\n      algorithm: 5\n",
        );
        let p = load(&text, &[]).unwrap();
        assert_eq!(
            params_of(&p, "train-rates[width=16]"),
            r#"{"algorithm":5,"epochs":18,"rate_outputs":["z_a"],"width":16}"#
        );
    }

    #[test]
    fn sets_on_the_base_flow_down_and_its_own_apply_last() {
        let p = load(BASE, &["train.epochs=2", "train-rates.width=8"]).unwrap();
        assert_eq!(
            params_of(&p, "train-rates"),
            r#"{"algorithm":5,"epochs":2,"rate_outputs":["z_a"],"width":8}"#
        );
        assert_eq!(
            params_of(&p, "train[algorithm=1]"),
            r#"{"algorithm":1,"epochs":2,"width":32}"#
        );
        assert_eq!(
            p.stage("train-rates").unwrap().overrides,
            ["epochs=2", "width=8"]
        );
        // An inherited key set on the extending stage alone leaves the base as written.
        let p = load(BASE, &["train-rates.epochs=1"]).unwrap();
        assert!(params_of(&p, "train[algorithm=5]").contains(r#""epochs":18"#));
        let e = load(BASE, &["train-rates.nope=1"]).unwrap_err().to_string();
        assert!(e.contains("no parameter `nope`"), "{e}");
    }

    #[test]
    fn a_parameter_inherited_is_located_in_the_base() {
        let p = load(BASE, &[]).unwrap();
        // `width` is written under `train` (line 12); `rate_outputs` under train-rates (17).
        assert!(p.param_location("train-rates", "width").ends_with(":12"));
        assert!(p
            .param_location("train-rates", "rate_outputs")
            .ends_with(":17"));
    }

    #[test]
    fn an_unknown_or_chained_base_is_refused_at_its_line() {
        let e = load(&BASE.replace("extends: train", "extends: trian"), &[])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(":14:") && e.contains("no stage `trian`") && e.contains("train-rates"),
            "{e}"
        );
        let chained = format!("{BASE}  again:\n    extends: train-rates\n");
        let e = load(&chained, &[]).unwrap_err().to_string();
        assert!(
            e.contains(":19:") && e.contains("`train-rates` extends another stage itself"),
            "{e}"
        );
        let e = load("stages:\n  a:\n    params: {x: 1}\n", &[])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(":2:") && e.contains("`cmd` must name a program"),
            "{e}"
        );
        // Setting a parameter that is a key of its own matrix stays refused.
        let own = BASE.replace(
            "    params:\n      algorithm: 5\n",
            "    matrix: {algorithm: [5]}\n    params:\n      algorithm: 5\n",
        );
        let e = load(&own, &[]).unwrap_err().to_string();
        assert!(e.contains("also a parameter"), "{e}");
    }
}
