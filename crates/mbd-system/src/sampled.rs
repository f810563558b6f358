//! One design: the values of a [`System`]'s sampled parameters, in the description's order,
//! bound to that order's names. A [`Sampled`] is made only by the system (its count and names
//! checked: [`System::sampled_values`], [`System::sampled_by_name`], [`System::nominal`]) and
//! read by name ([`Sampled::get`], [`Sampled::iter`]) wherever a person sees it, by position
//! ([`Sampled::as_slice`]) on the hot paths. It holds the values and a shared handle on the
//! system's list of names (no allocation beyond the values); [`System::instantiate`] and
//! [`System::values`] refuse a design whose names are not the system's.
//!
//! ```
//! let text = "format: 1\nname: one mass\nparameters:\n  m: {unit: kg, nominal: 2, range: [1, 3]}\n  c: {unit: N s/m, nominal: 5, range: [1, 9]}\n  k: {unit: N/m, value: 800}\nbodies:\n  b: {mass: m, dofs: [z]}\nelements:\n  spring: {kind: spring_damper, from: b, to: ground, k: k, c: c}\n";
//! let system = mbd_system::load_str(text, "one.yaml", &Default::default()).unwrap();
//! let by_name = system.sampled_by_name([("c", 4.0), ("m", 2.5)]).unwrap();
//! assert_eq!(by_name, system.sampled_values([2.5, 4.0]).unwrap());
//! assert_eq!(by_name.get("c"), Some(4.0));
//! let err = system.sampled_values([2.5]).unwrap_err().to_string();
//! assert!(err.contains("m, c"), "{err}");
//! ```

use std::sync::Arc;

use crate::System;

/// One design's sampled values, in the order of its system's sampled parameters (see the
/// module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct Sampled {
    names: Arc<[String]>,
    values: Vec<f64>,
}

/// A design that does not fit a system's sampled parameters.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SampledError {
    /// Values by position, another count than the system samples.
    #[error(
        "{got} sampled values given; system `{system}` samples {}, in this order: {}",
        expected.len(),
        expected.join(", ")
    )]
    Count {
        /// The system's name.
        system: String,
        /// How many values were given.
        got: usize,
        /// The sampled parameters, in the description's order.
        expected: Vec<String>,
    },
    /// Values by name: some unknown, missing or given twice.
    #[error("{}; system `{system}` samples {}", name_problems(unknown, missing, repeated), expected.join(", "))]
    Names {
        /// The system's name.
        system: String,
        /// Names the system does not sample.
        unknown: Vec<String>,
        /// Sampled parameters without a value.
        missing: Vec<String>,
        /// Names given more than once.
        repeated: Vec<String>,
        /// The sampled parameters, in the description's order.
        expected: Vec<String>,
    },
    /// A design made by a system with other sampled parameters.
    #[error(
        "a design of the sampled parameters {} given to system `{system}`, which samples {}",
        design.join(", "),
        expected.join(", ")
    )]
    OtherSystem {
        /// The system's name.
        system: String,
        /// The design's parameters.
        design: Vec<String>,
        /// The system's sampled parameters.
        expected: Vec<String>,
    },
}

/// The problems of [`SampledError::Names`], each kind named when present.
fn name_problems(unknown: &[String], missing: &[String], repeated: &[String]) -> String {
    [
        ("unknown sampled parameters", unknown),
        ("missing", missing),
        ("given twice", repeated),
    ]
    .iter()
    .filter(|(_, names)| !names.is_empty())
    .map(|(what, names)| format!("{what}: {}", names.join(", ")))
    .collect::<Vec<_>>()
    .join("; ")
}

impl Sampled {
    /// The value of sampled parameter `name`, if the system samples it.
    pub fn get(&self, name: &str) -> Option<f64> {
        self.names
            .iter()
            .position(|n| n == name)
            .map(|i| self.values[i])
    }

    /// `(name, value)` of every sampled parameter, in the description's order.
    pub fn iter(&self) -> impl ExactSizeIterator<Item = (&str, f64)> + '_ {
        self.names
            .iter()
            .map(String::as_str)
            .zip(self.values.iter().copied())
    }

    /// The sampled parameters' names, in the description's order.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// The values in the description's order (the hot paths: engine, training).
    pub fn as_slice(&self) -> &[f64] {
        &self.values
    }

    /// The values in the description's order, to change in place (the count stays).
    pub fn as_mut_slice(&mut self) -> &mut [f64] {
        &mut self.values
    }

    /// Sets sampled parameter `name` to `value`; `false` (and nothing changed) when the
    /// system does not sample it.
    pub fn set(&mut self, name: &str, value: f64) -> bool {
        match self.names.iter().position(|n| n == name) {
            Some(i) => {
                self.values[i] = value;
                true
            }
            None => false,
        }
    }

    /// The values, in the description's order.
    pub fn into_values(self) -> Vec<f64> {
        self.values
    }

    /// How many sampled parameters.
    pub fn len(&self) -> usize {
        self.values.len()
    }

    /// Whether the system samples no parameter.
    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }

    /// Whether this design's names are `system`'s sampled parameters (the same shared list, or
    /// an equal one from another compile of the description).
    pub fn fits(&self, system: &System) -> bool {
        Arc::ptr_eq(&self.names, &system.sampled_list) || self.names == system.sampled_list
    }
}

impl System {
    fn sampled_expected(&self) -> Vec<String> {
        self.sampled_list.to_vec()
    }

    /// A design from its values in the description's order ([`System::sampled_names`]);
    /// another count is refused, naming the parameters expected.
    pub fn sampled_values(&self, values: impl Into<Vec<f64>>) -> Result<Sampled, SampledError> {
        let values = values.into();
        if values.len() != self.sampled_list.len() {
            return Err(SampledError::Count {
                system: self.name.clone(),
                got: values.len(),
                expected: self.sampled_expected(),
            });
        }
        Ok(Sampled {
            names: Arc::clone(&self.sampled_list),
            values,
        })
    }

    /// A design from `(name, value)` pairs in any order: every sampled parameter exactly once;
    /// unknown, missing and repeated names are refused, each named.
    pub fn sampled_by_name<N: AsRef<str>>(
        &self,
        pairs: impl IntoIterator<Item = (N, f64)>,
    ) -> Result<Sampled, SampledError> {
        let mut values: Vec<Option<f64>> = vec![None; self.sampled_list.len()];
        let (mut unknown, mut repeated) = (Vec::new(), Vec::new());
        for (name, value) in pairs {
            let name = name.as_ref();
            match self.sampled_list.iter().position(|n| n == name) {
                Some(i) if values[i].is_some() => repeated.push(name.to_owned()),
                Some(i) => values[i] = Some(value),
                None => unknown.push(name.to_owned()),
            }
        }
        let missing: Vec<String> = self
            .sampled_list
            .iter()
            .zip(&values)
            .filter(|(_, v)| v.is_none())
            .map(|(n, _)| n.clone())
            .collect();
        if !(unknown.is_empty() && missing.is_empty() && repeated.is_empty()) {
            return Err(SampledError::Names {
                system: self.name.clone(),
                unknown,
                missing,
                repeated,
                expected: self.sampled_expected(),
            });
        }
        Ok(Sampled {
            names: Arc::clone(&self.sampled_list),
            values: values.into_iter().flatten().collect(),
        })
    }

    /// `design` checked to be one of this system's (see [`Sampled::fits`]).
    pub fn check_design(&self, design: &Sampled) -> Result<(), SampledError> {
        if design.fits(self) {
            Ok(())
        } else {
            Err(SampledError::OtherSystem {
                system: self.name.clone(),
                design: design.names.to_vec(),
                expected: self.sampled_expected(),
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn two() -> System {
        let text = "format: 1\nname: two\nparameters:\n  m: {unit: kg, nominal: 2, range: [1, 3]}\n  c: {unit: N s/m, nominal: 5, range: [1, 9]}\n  k: {unit: N/m, value: 800}\nbodies:\n  b: {mass: m, dofs: [z]}\nelements:\n  spring: {kind: spring_damper, from: b, to: ground, k: k, c: c}\n";
        crate::load_str(text, "two.yaml", &Default::default()).unwrap()
    }

    #[test]
    fn by_name_and_by_position_are_the_same_design() {
        let s = two();
        let by_name = s.sampled_by_name([("c", 4.0), ("m", 2.5)]).unwrap();
        let by_position = s.sampled_values(vec![2.5, 4.0]).unwrap();
        assert_eq!(by_name, by_position);
        assert_eq!(by_name.as_slice(), [2.5, 4.0]);
        assert_eq!(by_name.iter().collect::<Vec<_>>(), [("m", 2.5), ("c", 4.0)]);
        assert_eq!((by_name.get("m"), by_name.get("k")), (Some(2.5), None));
        assert_eq!(s.nominal().as_slice(), [2.0, 5.0]);
    }

    #[test]
    fn a_wrong_count_is_refused_naming_the_parameters() {
        let s = two();
        for wrong in [vec![], vec![1.0], vec![1.0, 2.0, 3.0]] {
            let n = wrong.len();
            let err = s.sampled_values(wrong).unwrap_err();
            assert!(matches!(err, SampledError::Count { got, .. } if got == n));
            let text = err.to_string();
            assert!(text.contains("samples 2, in this order: m, c"), "{text}");
        }
    }

    #[test]
    fn unknown_missing_and_repeated_names_are_refused_each_named() {
        let s = two();
        let err = s
            .sampled_by_name([("m", 1.0), ("mass", 2.0), ("m", 3.0)])
            .unwrap_err();
        let text = err.to_string();
        assert_eq!(
            text,
            "unknown sampled parameters: mass; missing: c; given twice: m; system `two` samples m, c"
        );
        // A fixed parameter is not sampled: unknown as a design's name.
        let err = s
            .sampled_by_name([("m", 1.0), ("c", 2.0), ("k", 3.0)])
            .unwrap_err();
        assert!(matches!(&err, SampledError::Names { unknown, missing, .. }
            if unknown == &["k"] && missing.is_empty()));
    }

    #[test]
    fn a_design_of_another_system_is_refused() {
        let s = two();
        let other = crate::load_str(
            "format: 1\nname: one\nparameters:\n  m: {unit: kg, nominal: 2, range: [1, 3]}\nbodies:\n  b: {mass: m, dofs: [z]}\nelements:\n  spring: {kind: spring_damper, from: b, to: ground, k: 800}\n",
            "one.yaml",
            &Default::default(),
        )
        .unwrap();
        let design = other.nominal();
        let err = s.instantiate(&design).unwrap_err().to_string();
        assert!(err.contains("m, c"), "{err}");
        assert!(s.values(&design).is_err());
        // Another compile of the same description: the same names, accepted.
        assert!(two().nominal().fits(&s));
        s.instantiate(&two().nominal()).unwrap();
    }
}
