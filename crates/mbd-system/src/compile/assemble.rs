//! The flat assembly of the compiled elements and loads: per DOF, the groups of force terms
//! (a coefficient, a sign and the element or load it comes from) the engine sums.

use super::*;

/// Per DOF, the generalised force as coefficient groups, accumulated in a fixed order by kind:
/// spring-dampers and tables, then loads, then contacts, each in declaration order.
pub(super) fn assemble(
    bodies: &[Body],
    dofs: &[Dof],
    elements: &[Element],
    loads: &[Load],
) -> Vec<Vec<Group>> {
    let mut out: Vec<Vec<Group>> = vec![Vec::new(); dofs.len()];
    // A force `F` (downward) applied at a point `x` of a body: `F` on z, `-x F` on pitch.
    let mut add = |end: &End, applied_sign: f64, source: Source| {
        let End::Body { body, x } = end else { return };
        let b = &bodies[*body];
        if let Some(z) = b.z {
            push_term(&mut out[z], None, applied_sign, source);
        }
        if let (Some(p), Some(x)) = (b.pitch, x) {
            if !x.is_zero() {
                let (s, magnitude) = x.split_sign();
                push_term(
                    &mut out[p],
                    Some(magnitude.clone()),
                    -applied_sign * s,
                    source,
                );
            }
        }
    };
    let order = elements
        .iter()
        .enumerate()
        .filter(|(_, e)| !e.law.is_contact())
        .map(|(i, _)| Some(i))
        .chain(std::iter::once(None))
        .chain(
            elements
                .iter()
                .enumerate()
                .filter(|(_, e)| e.law.is_contact())
                .map(|(i, _)| Some(i)),
        );
    for item in order {
        match item {
            Some(i) => {
                // The element pushes its upper end up (-f) and its lower end down (+f).
                add(&elements[i].from, -1.0, Source::Element(i));
                add(&elements[i].to, 1.0, Source::Element(i));
            }
            None => {
                for (i, l) in loads.iter().enumerate() {
                    add(&l.at, 1.0, Source::Load(i));
                }
            }
        }
    }
    out
}

fn push_term(groups: &mut Vec<Group>, coefficient: Option<Expr>, sign: f64, source: Source) {
    let key = coefficient.as_ref().map(|e| e.to_string());
    match groups
        .iter_mut()
        .find(|g| g.coefficient.as_ref().map(|e| e.to_string()) == key)
    {
        Some(g) => g.terms.push((source, sign)),
        None => groups.push(Group {
            coefficient,
            terms: vec![(source, sign)],
        }),
    }
}
