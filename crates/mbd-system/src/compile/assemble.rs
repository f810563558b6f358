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
    // A force `F` along `axis` applied at a point `r` of a body: `F` on the translation along
    // the axis, `F c` on each rotation that moves the point along it (`c` the coordinate of
    // `Axis::rotations` with its sign: for `z`, `-x F` on pitch and `y F` on roll).
    let mut add = |end: &End, axis: Axis, applied_sign: f64, source: Source| {
        let End::Body { body, .. } = end else { return };
        let b = &bodies[*body];
        if let Some(t) = b.dof(axis.translation()) {
            push_term(&mut out[t], None, applied_sign, source);
        }
        for (kind, coordinate, sign) in axis.rotations() {
            if let (Some(r), Some(c)) = (b.dof(kind), end.coordinate(coordinate)) {
                if !c.is_zero() {
                    let (s, magnitude) = c.split_sign();
                    push_term(
                        &mut out[r],
                        Some(magnitude.clone()),
                        applied_sign * sign * s,
                        source,
                    );
                }
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
                // The element pushes its upper end against its direction (-f) and its lower
                // end along it (+f).
                let e = &elements[i];
                add(&e.from, e.direction, -1.0, Source::Element(i));
                add(&e.to, e.direction, 1.0, Source::Element(i));
            }
            None => {
                for (i, l) in loads.iter().enumerate() {
                    add(&l.at, l.direction, 1.0, Source::Load(i));
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
