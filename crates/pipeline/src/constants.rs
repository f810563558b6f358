//! Shared values of a pipeline file: one source for a fact several stages use.
//!
//! A pipeline file may hold a top-level `constants:` mapping. A stage parameter whose whole
//! value is the string `${constants.NAME}` (anywhere in the parameter tree, lists and
//! mappings included) takes that constant's value when the file is loaded, before identities
//! are computed:
//!
//! ```yaml
//! constants:
//!   gravity: 9.81
//! stages:
//!   simulate: {cmd: [simulate], params: {gravity: "${constants.gravity}"}}
//!   weights:  {cmd: [weights],  params: {gravity: "${constants.gravity}"}}
//! ```
//!
//! `--set constants.gravity=9.8` therefore reaches every stage that references it and changes
//! each one's identity; `--set simulate.gravity=...` on a referencing parameter is refused
//! (it would split the fact again). A reference to an unknown constant is an error naming it.

use serde_json::{Map, Value};

/// The top-level key and the `--set` prefix.
pub const SECTION: &str = "constants";

/// The constant a value refers to: `Some("gravity")` for the string `${constants.gravity}`.
pub fn reference(v: &Value) -> Option<&str> {
    v.as_str()?
        .strip_prefix("${constants.")?
        .strip_suffix('}')
        .filter(|n| !n.is_empty())
}

/// Replaces every reference in `v` by its constant's value; `Err(name)` for the first
/// reference to a constant that `constants` does not hold.
pub fn substitute(v: &mut Value, constants: &Map<String, Value>) -> Result<(), String> {
    if let Some(name) = reference(v) {
        let value = constants.get(name).ok_or_else(|| name.to_owned())?;
        *v = value.clone();
        return Ok(());
    }
    match v {
        Value::Array(items) => items.iter_mut().try_for_each(|x| substitute(x, constants)),
        Value::Object(map) => map.values_mut().try_for_each(|x| substitute(x, constants)),
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn references_are_whole_strings_only() {
        assert_eq!(reference(&json!("${constants.g}")), Some("g"));
        for not in [
            json!("${constants.}"),
            json!("x ${constants.g}"),
            json!("${g}"),
            json!(1),
        ] {
            assert_eq!(reference(&not), None, "{not}");
        }
    }

    #[test]
    fn substitutes_through_lists_and_mappings() {
        let c = json!({"g": 9.81, "r": [1, 2]});
        let mut v = json!({"a": "${constants.g}", "b": ["${constants.r}", {"c": "${constants.g}"}], "d": "text"});
        substitute(&mut v, c.as_object().unwrap()).unwrap();
        assert_eq!(
            v,
            json!({"a": 9.81, "b": [[1, 2], {"c": 9.81}], "d": "text"})
        );
        let mut v = json!({"a": "${constants.h}"});
        assert_eq!(substitute(&mut v, c.as_object().unwrap()), Err("h".into()));
    }
}
