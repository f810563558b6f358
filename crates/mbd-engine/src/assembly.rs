//! The rigid DOFs' generalised forces from the element forces, as flat lists built once per
//! model from its coefficient groups ([`mbd_system::model::Model::assembly`]): per DOF a run of
//! groups, per group its coefficient and a run of signed terms.
//!
//! The arithmetic is the groups' as written: per group `sum = s_1 f_1`, then `sum += s_j f_j`
//! (`s = +-1`, so `s f` is `f` or exactly `-f` and `sum + (-f)` is `sum - f`), `c sum` with the
//! coefficient `c` (1 when none: `1 sum` is `sum` exactly); the DOF's total is its first
//! group's value, each further group added in order. Flat runs of plain indices replace the
//! nested lists and enums of the description: fewer loads and branches per step.

use mbd_system::model::Model;
use mbd_system::system::Source;

/// One coefficient group: its coefficient (1 when none), its terms `terms[first..end]`, and
/// whether it starts the DOF's total (the DOF's first group) or is added to it.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Group {
    coefficient: f64,
    terms: (u32, u32),
    starts: bool,
}

/// The compiled coefficient groups of a model's rigid DOFs.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Assembly {
    /// Per DOF, its groups `groups[first..end]`.
    dofs: Vec<(u32, u32)>,
    groups: Vec<Group>,
    /// Per term, the index of its value (`< elements`: an element force; beyond: a load) and
    /// its sign (+1 or -1).
    terms: Vec<(u32, f64)>,
    /// The number of elements: where the loads' values begin.
    elements: usize,
    /// The loads' forces (N).
    loads: Vec<f64>,
}

impl Assembly {
    /// The groups of `model`'s DOFs; groups without terms are left out (they add nothing).
    pub(crate) fn of(model: &Model) -> Self {
        let elements = model.elements.len();
        let index = |s: &Source| -> u32 {
            let i = match *s {
                Source::Element(i) => i,
                Source::Load(i) => elements + i,
            };
            u32::try_from(i).expect("fewer than 2^32 elements and loads")
        };
        let len = |v: usize| u32::try_from(v).expect("fewer than 2^32 terms");
        let (mut dofs, mut groups, mut terms) = (Vec::new(), Vec::new(), Vec::new());
        for dof_groups in &model.assembly {
            let first_group = len(groups.len());
            for (gi, g) in dof_groups.iter().enumerate() {
                if g.terms.is_empty() {
                    continue;
                }
                let first_term = len(terms.len());
                terms.extend(
                    g.terms
                        .iter()
                        .map(|(s, sign)| (index(s), if *sign < 0.0 { -1.0 } else { 1.0 })),
                );
                groups.push(Group {
                    coefficient: g.coefficient.unwrap_or(1.0),
                    terms: (first_term, len(terms.len())),
                    starts: gi == 0,
                });
            }
            dofs.push((first_group, len(groups.len())));
        }
        Self {
            dofs,
            groups,
            terms,
            elements,
            loads: model.loads.iter().map(|l| l.force).collect(),
        }
    }

    /// The generalised force of every rigid DOF (N or N m) from the element forces `force`
    /// (N), into `out[..dofs]`.
    #[inline]
    pub(crate) fn forces(&self, force: &[f64], out: &mut [f64]) {
        let value = |&(i, sign): &(u32, f64)| {
            let i = i as usize;
            sign * if i < self.elements {
                force[i]
            } else {
                self.loads[i - self.elements]
            }
        };
        for (o, &(g0, g1)) in out.iter_mut().zip(&self.dofs) {
            let mut total = 0.0;
            for g in &self.groups[g0 as usize..g1 as usize] {
                let (t0, t1) = g.terms;
                let terms = &self.terms[t0 as usize..t1 as usize];
                let sum = terms[1..]
                    .iter()
                    .fold(value(&terms[0]), |sum, t| sum + value(t));
                let g_value = g.coefficient * sum;
                total = if g.starts { g_value } else { total + g_value };
            }
            *o = total;
        }
    }
}
