//! The tensor layout of a described system (`docs/learning.md`, Tensors): which columns are
//! the operator's inputs, outputs and derivative targets, derived from the system description
//! and stored in `model.json`, so no channel count or position is written in code.
//!
//! - inputs `[T, 1 + E + P]`: `t`, the excitation columns (`eta_<element>`, the profile under
//!   each element that reads one, followed by its own rate `eta_<element>_v` where the element
//!   is a damper that reads that rate) and the sampled parameters (the description's order);
//! - outputs `[T, S + F + R]`: the `S` solutions (the rigid DOFs' displacements, then the
//!   stored displacement columns of moving points and sensors), the `F` element forces stored
//!   (`p_<contact>`, `f_<element>`) and, when a training asks for them
//!   ([`Layout::with_rate_outputs`]), `R` stored velocities or accelerations the network
//!   outputs directly (`z_c_a`, `z_mid_a`), supervised by their exact columns like any output;
//! - derivative targets `[T, D]`: the exact `_v` and `_a` of the `D` rigid DOFs (the first `D`
//!   outputs);
//! - equations: the DOFs whose forces close on the outputs and the excitations
//!   ([`mbd_system::System::equation_dofs`]): the ODE losses and the magnitude weights use them;
//! - records: what a reader takes of each simulated sample, as named ranges ([`Record`]:
//!   displacements, `_v`, `_a`, excitations; [`Layout::training_record`],
//!   [`Layout::weights_record`]) and the input channels' groups ([`InputRanges`]), one
//!   composition for the data path, the statistics and the weights.
//!
//! For the vehicle-track description this is today's `t, eta_1..eta_4`, the 14 parameters
//! (19 inputs), `z_c .. z_w4, z_r1..z_r4, p_1..p_4` (18 outputs, 14 solutions) and the ten
//! vehicle DOFs, all with equations.

use mbd_system::system::{Quantity, Role};
use mbd_system::System;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::ops::Range;

/// The time column.
pub const TIME: &str = "t";

/// A system's channel layout.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Layout {
    /// Sampled parameters (description order).
    pub params: Vec<String>,
    /// Excitation columns.
    pub excitations: Vec<String>,
    /// Output columns: solutions, then forces, then the rate outputs.
    pub outputs: Vec<String>,
    /// How many outputs are solutions (displacements).
    pub solutions: usize,
    /// How many outputs (the last) are stored rates the network outputs directly
    /// ([`Layout::with_rate_outputs`]; absent in `model.json`: none).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub rates: usize,
    /// The rigid DOFs (the first outputs), derivative targets.
    pub dofs: Vec<String>,
    /// Indices into `dofs` of the DOFs with an equation.
    pub equations: Vec<usize>,
    /// Unit of every named column (inputs, outputs, `_v`, `_a`).
    pub units: BTreeMap<String, String>,
}

impl Layout {
    /// The layout of `system`.
    pub fn of(system: &System) -> Self {
        let names = |role| -> Vec<String> {
            system
                .channels_of(role)
                .into_iter()
                .map(|i| system.channels[i].name.clone())
                .collect()
        };
        let excitations = names(Role::Excitation);
        let mut outputs = names(Role::Solution);
        let solutions = outputs.len();
        outputs.extend(names(Role::Force));
        let dofs: Vec<String> = system.dofs.iter().map(|d| d.name.clone()).collect();
        debug_assert!(
            outputs.iter().zip(&dofs).all(|(o, d)| o == d),
            "DOF columns lead the outputs"
        );
        let params: Vec<String> = system
            .sampled_names()
            .into_iter()
            .map(str::to_owned)
            .collect();
        let out_refs: Vec<&str> = outputs.iter().map(String::as_str).collect();
        let in_refs: Vec<&str> = excitations.iter().map(String::as_str).collect();
        let equations = system.equation_dofs(&out_refs, &in_refs);
        let mut units: BTreeMap<String, String> = system
            .channels
            .iter()
            .map(|c| (c.name.clone(), c.unit.clone()))
            .collect();
        for i in system.sampled() {
            let p = &system.parameters[i];
            units.insert(p.name.clone(), p.unit.clone());
        }
        units.insert(TIME.to_owned(), "s".to_owned());
        Self {
            params,
            excitations,
            outputs,
            solutions,
            rates: 0,
            dofs,
            equations,
            units,
        }
    }

    /// This layout with the stored rate columns `names` (`_v` or `_a` of a DOF or a sensor)
    /// appended to the outputs, in the given order: the network outputs them directly and
    /// every reader of such a column (the indices, the histories) takes the output instead of
    /// a difference of the displacement. A name that is not a stored rate of `system`, or is
    /// given twice, is refused with the stored rates listed.
    pub fn with_rate_outputs(mut self, system: &System, names: &[String]) -> crate::Result<Self> {
        let stored: Vec<&str> = system
            .channels
            .iter()
            .filter(|c| is_rate(c.quantity))
            .map(|c| c.name.as_str())
            .collect();
        for (k, name) in names.iter().enumerate() {
            if !stored.contains(&name.as_str()) {
                return Err(crate::Error::RateOutputs(format!(
                    "`{name}` is not a velocity or acceleration column the description `{}` stores (its rates: {})",
                    system.name,
                    stored.join(", ")
                )));
            }
            if names[..k].contains(name) {
                return Err(crate::Error::RateOutputs(format!(
                    "`{name}` is given twice"
                )));
            }
        }
        self.outputs.truncate(self.outputs.len() - self.rates);
        self.outputs.extend(names.iter().cloned());
        self.rates = names.len();
        Ok(self)
    }

    /// Whether this is `system`'s layout (with its rate outputs): false for a model of
    /// another description or an edited `model.json`.
    pub fn follows(&self, system: &System) -> bool {
        Layout::of(system)
            .with_rate_outputs(system, self.rate_outputs())
            .is_ok_and(|l| l == *self)
    }

    /// The derivative order of output `k` when it is a rate output (1: a velocity, 2: an
    /// acceleration; from its unit, `.../s` or `.../s^2` as the description's compiler gives
    /// every stored rate); `None` for a displacement or a force.
    pub fn rate_order(&self, k: usize) -> Option<u8> {
        (k >= self.forces().end && k < self.outputs.len()).then(|| {
            if self.unit(&self.outputs[k]).ends_with("^2") {
                2
            } else {
                1
            }
        })
    }

    /// The name output `k` is reported under beside the derived channels (`channel_errors`,
    /// the calibration's bands, `coverage`): its column name, or `NAME (output)` for a rate
    /// the network outputs whose name is also that of a DOF's velocity or acceleration (the
    /// central difference of its displacement, reported under the plain name).
    pub fn output_label(&self, k: usize) -> String {
        let name = &self.outputs[k];
        let dof_rate = self.velocities().contains(name) || self.accelerations().contains(name);
        if self.rate_order(k).is_some() && dof_rate {
            format!("{name} (output)")
        } else {
            name.clone()
        }
    }

    /// The rate outputs ([`Layout::with_rate_outputs`]; empty for the paper's networks).
    pub fn rate_outputs(&self) -> &[String] {
        &self.outputs[self.outputs.len() - self.rates..]
    }

    /// Input columns: `t`, the excitations, the parameters.
    pub fn inputs(&self) -> Vec<String> {
        std::iter::once(TIME.to_owned())
            .chain(self.excitations.iter().cloned())
            .chain(self.params.iter().cloned())
            .collect()
    }

    /// Number of input channels.
    pub fn n_inputs(&self) -> usize {
        1 + self.excitations.len() + self.params.len()
    }

    /// Number of output channels.
    pub fn n_outputs(&self) -> usize {
        self.outputs.len()
    }

    /// Number of rigid DOFs (derivative targets).
    pub fn n_dofs(&self) -> usize {
        self.dofs.len()
    }

    /// Number of excitation channels.
    pub fn n_excitations(&self) -> usize {
        self.excitations.len()
    }

    /// The force outputs (channel indices).
    pub fn forces(&self) -> std::ops::Range<usize> {
        self.solutions..self.outputs.len() - self.rates
    }

    /// `_v` columns of the DOFs.
    pub fn velocities(&self) -> Vec<String> {
        self.dofs.iter().map(|d| format!("{d}_v")).collect()
    }

    /// `_a` columns of the DOFs.
    pub fn accelerations(&self) -> Vec<String> {
        self.dofs.iter().map(|d| format!("{d}_a")).collect()
    }

    /// The simulation columns a dataset is read from: `sample_id`, `t`, then the columns of
    /// [`Layout::training_record`].
    pub fn simulation_columns(&self) -> Vec<String> {
        let mut c = vec![pino_data::schema::SAMPLE_ID.to_owned(), TIME.to_owned()];
        c.extend(self.record_columns(&self.outputs));
        c
    }

    /// The record training reads per sample: every output (solutions, forces, rate
    /// outputs), the `_v`, the `_a`, the excitations.
    pub fn training_record(&self) -> Record {
        Record::stacked(self.outputs.len(), self.dofs.len(), self.excitations.len())
    }

    /// The record the magnitude weights read per sample: the solutions (no forces), the
    /// `_v`, the `_a`, the excitations.
    pub fn weights_record(&self) -> Record {
        Record::stacked(self.solutions, self.dofs.len(), self.excitations.len())
    }

    /// The columns of a record whose first group is `first` (the outputs of
    /// [`Layout::training_record`], the solutions of [`Layout::weights_record`]), in the order
    /// of its ranges.
    pub fn record_columns(&self, first: &[String]) -> Vec<String> {
        let mut c = first.to_vec();
        c.extend(self.velocities());
        c.extend(self.accelerations());
        c.extend(self.excitations.iter().cloned());
        c
    }

    /// Where each group sits among the input channels.
    pub fn input_ranges(&self) -> InputRanges {
        let excitations = 1..1 + self.excitations.len();
        let params = excitations.end..excitations.end + self.params.len();
        InputRanges {
            time: 0,
            excitations,
            params,
        }
    }

    /// Unit of column `name` (`-` when unknown).
    pub fn unit(&self, name: &str) -> &str {
        self.units.get(name).map_or("-", String::as_str)
    }

    /// The magnitude-weight columns, one per equation: `phi_<dof>`.
    pub fn phi_columns(&self) -> Vec<String> {
        self.equations
            .iter()
            .map(|&i| pino_data::system::phi_column(&self.dofs[i]))
            .collect()
    }

    /// The series sizes of one sample's stored record.
    pub fn series_shape(&self) -> SeriesShape {
        SeriesShape {
            outputs: self.outputs.len(),
            dofs: self.dofs.len(),
            excitations: self.excitations.len(),
        }
    }
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

/// Whether a stored quantity is a velocity or an acceleration.
fn is_rate(q: Quantity) -> bool {
    matches!(q, Quantity::Dof(_, o) | Quantity::Sensor(_, o) if o > 0)
}

/// A record's channel groups as named ranges of its columns (one composition for every
/// reader: the displacement group first, then the DOFs' `_v` and `_a`, then the excitations).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Record {
    /// The outputs (training) or the solutions (weights).
    pub displacements: Range<usize>,
    /// The rigid DOFs' exact velocities.
    pub velocities: Range<usize>,
    /// The rigid DOFs' exact accelerations.
    pub accelerations: Range<usize>,
    /// The excitations.
    pub excitations: Range<usize>,
}

impl Record {
    /// `first` displacement channels, `dofs` velocities and accelerations, `excitations`.
    fn stacked(first: usize, dofs: usize, excitations: usize) -> Self {
        let velocities = first..first + dofs;
        let accelerations = velocities.end..velocities.end + dofs;
        let excitations = accelerations.end..accelerations.end + excitations;
        Self {
            displacements: 0..first,
            velocities,
            accelerations,
            excitations,
        }
    }

    /// Number of columns.
    pub fn width(&self) -> usize {
        self.excitations.end
    }
}

/// The input tensor's channel groups `[t, excitations, parameters]`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct InputRanges {
    /// The time channel.
    pub time: usize,
    /// The excitations.
    pub excitations: Range<usize>,
    /// The sampled parameters.
    pub params: Range<usize>,
}

/// Channels per time point of a stored sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SeriesShape {
    /// Outputs.
    pub outputs: usize,
    /// Derivative targets (each of `v` and `a`).
    pub dofs: usize,
    /// Excitations.
    pub excitations: usize,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn system(file: &str) -> System {
        let path = format!("{}/../../systems/{file}", env!("CARGO_MANIFEST_DIR"));
        let text = std::fs::read_to_string(&path).unwrap();
        mbd_system::load_str(&text, file, &Default::default()).unwrap()
    }

    /// The vehicle-track description gives the historical tensors exactly.
    #[test]
    fn vehicle_track_layout_is_the_papers() {
        let l = Layout::of(&system("vtcd.yaml"));
        assert_eq!(
            (l.n_inputs(), l.n_outputs(), l.solutions, l.n_dofs()),
            (19, 18, 14, 10)
        );
        assert_eq!(l.excitations, ["eta_1", "eta_2", "eta_3", "eta_4"]);
        assert_eq!(
            &l.outputs[10..],
            ["z_r1", "z_r2", "z_r3", "z_r4", "p_1", "p_2", "p_3", "p_4"]
        );
        assert_eq!(l.params[0], "m_c");
        assert_eq!(l.equations, (0..10).collect::<Vec<_>>());
        assert_eq!(l.phi_columns()[1], "phi_beta_c");
        assert_eq!(l.unit("beta_c_a"), "rad/s^2");
        // One composition of records: named ranges over the columns each reader lists.
        let r = l.training_record();
        let cols = l.simulation_columns();
        assert_eq!(r.width() + 2, cols.len());
        assert_eq!(cols[2 + r.velocities.start], "z_c_v");
        assert_eq!(cols[2 + r.accelerations.end - 1], "z_w4_a");
        assert_eq!(cols[2 + r.excitations.start], "eta_1");
        let w = l.weights_record();
        assert_eq!((w.displacements.end, w.width()), (14, 14 + 20 + 4));
        let i = l.input_ranges();
        assert_eq!(l.inputs()[i.params.start], "m_c");
        assert_eq!((i.excitations, i.params.end), (1..5, l.n_inputs()));
        let back: Layout = serde_json::from_str(&serde_json::to_string(&l).unwrap()).unwrap();
        assert_eq!(back, l);
    }

    /// Rate outputs follow the forces; the forces, records and statistics names keep their
    /// places; the paper's layout serialises as before (no `rates` key).
    #[test]
    fn rate_outputs_are_appended_after_the_forces_and_checked() {
        let sys = system("vtcd.yaml");
        let plain = Layout::of(&sys);
        assert!(!serde_json::to_string(&plain).unwrap().contains("rates"));
        let names = ["z_c_a".to_owned(), "beta_c_v".to_owned()];
        let l = plain.clone().with_rate_outputs(&sys, &names).unwrap();
        assert_eq!((l.n_outputs(), l.rates), (20, 2));
        assert_eq!(l.forces(), plain.forces());
        assert_eq!(l.rate_outputs(), names);
        assert_eq!(
            (l.rate_order(18), l.rate_order(19), l.rate_order(17)),
            (Some(2), Some(1), None)
        );
        assert!(l.follows(&sys) && plain.follows(&sys));
        assert!(!l.follows(&system("bridge.yaml")));
        // A rate output is told from the difference of its displacement by its label.
        assert_eq!(
            (l.output_label(18), l.output_label(19), l.output_label(17)),
            (
                "z_c_a (output)".to_owned(),
                "beta_c_v (output)".to_owned(),
                "p_4".to_owned()
            )
        );
        let back: Layout = serde_json::from_str(&serde_json::to_string(&l).unwrap()).unwrap();
        assert_eq!(back, l);
        // Asking again replaces the set; the record reads the rate columns with the outputs.
        let again = l.with_rate_outputs(&sys, &names[..1]).unwrap();
        assert_eq!(again.rate_outputs(), ["z_c_a"]);
        assert_eq!(again.simulation_columns()[2 + 18], "z_c_a");
        for (bad, why) in [
            (
                vec!["z_c".to_owned()],
                "`z_c` is not a velocity or acceleration column",
            ),
            (
                vec!["p_1_a".to_owned()],
                "its rates: z_c_v, beta_c_v, z_t1_v",
            ),
            (
                vec!["z_c_a".to_owned(), "z_c_a".to_owned()],
                "`z_c_a` is given twice",
            ),
        ] {
            let e = plain
                .clone()
                .with_rate_outputs(&sys, &bad)
                .unwrap_err()
                .to_string();
            assert!(
                e.starts_with("params.rate_outputs: ") && e.contains(why),
                "{e}"
            );
        }
        // The bridge's sensor acceleration is a stored rate too.
        let b = system("bridge.yaml");
        let bl = Layout::of(&b)
            .with_rate_outputs(&b, &["z_mid_a".to_owned()])
            .unwrap();
        assert_eq!(bl.rate_order(bl.n_outputs() - 1), Some(2));
        // A sensor's rate has no difference beside it: its plain name.
        assert_eq!(bl.output_label(bl.n_outputs() - 1), "z_mid_a");
    }

    /// The bridge's vehicle has its equation through the deck deflection under it; a
    /// description whose outputs leave a beam point out has none there.
    #[test]
    fn equations_close_on_the_outputs() {
        let l = Layout::of(&system("bridge.yaml"));
        assert_eq!(l.dofs, ["z_v"]);
        assert_eq!(l.equations, [0]);
        assert!(
            l.outputs.contains(&"z_b1".to_owned())
                && l.outputs.contains(&"f_suspension".to_owned())
        );
        assert_eq!(l.excitations, ["eta_suspension", "eta_suspension_v"]);
        assert_eq!(l.unit("eta_suspension_v"), "m/s");
        let q = Layout::of(&system("quarter-car.yaml"));
        assert_eq!(q.equations, [0, 1]);
        assert_eq!(q.excitations, ["eta_tyre"]);
    }
}
