//! The parameter table's order and structure: the derived parameters in dependency order (a
//! cycle named with its path), and the values fixed for every sample (what counts are
//! evaluated from).

use super::*;

/// Topological order of the derived parameters; a cycle is reported with its path.
pub(super) fn derived_order(
    raw: &RawDescription,
    params: &[Parameter],
    diag: &mut Diagnostics,
) -> Vec<usize> {
    let n = params.len();
    let mut state = vec![0u8; n]; // 0 new, 1 on the path, 2 done
    let mut order = Vec::new();
    pub(super) fn visit(
        i: usize,
        params: &[Parameter],
        state: &mut [u8],
        path: &mut Vec<usize>,
        order: &mut Vec<usize>,
    ) -> Result<(), Vec<usize>> {
        if state[i] == 2 {
            return Ok(());
        }
        if state[i] == 1 {
            let start = path.iter().position(|&j| j == i).unwrap_or(0);
            let mut cycle = path[start..].to_vec();
            cycle.push(i);
            return Err(cycle);
        }
        state[i] = 1;
        path.push(i);
        if let ParamSource::Derived(e) = &params[i].source {
            let mut deps = Vec::new();
            collect_ids(e, &mut deps);
            for d in deps {
                visit(d, params, state, path, order)?;
            }
            order.push(i);
        }
        path.pop();
        state[i] = 2;
        Ok(())
    }
    for i in 0..n {
        let mut path = Vec::new();
        if let Err(cycle) = visit(i, params, &mut state, &mut path, &mut order) {
            let names: Vec<&str> = cycle.iter().map(|&j| params[j].name.as_str()).collect();
            diag.push(
                raw.parameters[cycle[0]].pos,
                format!(
                    "parameters: derived parameters form a cycle: {}",
                    names.join(" -> ")
                ),
            );
            for &j in &cycle {
                state[j] = 2;
            }
        }
    }
    order
}

/// Values of the parameters that are the same for every sample (fixed, or derived only from
/// fixed ones); `None` for those that vary.
pub(super) fn structural_values(params: &[Parameter], order: &[usize]) -> Vec<Option<f64>> {
    let mut v: Vec<Option<f64>> = params
        .iter()
        .map(|p| match p.source {
            ParamSource::Fixed(x) => Some(x),
            _ => None,
        })
        .collect();
    for &i in order {
        if let ParamSource::Derived(e) = &params[i].source {
            let mut ids = Vec::new();
            collect_ids(e, &mut ids);
            if ids.iter().all(|&j| v[j].is_some()) {
                let vals: Vec<f64> = v.iter().map(|x| x.unwrap_or(f64::NAN)).collect();
                v[i] = Some(e.eval(&vals));
            }
        }
    }
    v
}

pub(super) fn structural_count(
    e: &Expr,
    params: &[Parameter],
    fixed: &[Option<f64>],
) -> Result<usize, String> {
    let mut ids = Vec::new();
    collect_ids(e, &mut ids);
    if let Some(&j) = ids.iter().find(|&&j| fixed[j].is_none()) {
        return Err(format!(
            "a count must be the same for every sample, but `{}` varies (sampled, or derived from a sampled parameter)",
            params[j].name
        ));
    }
    let vals: Vec<f64> = fixed.iter().map(|x| x.unwrap_or(f64::NAN)).collect();
    let v = e.eval(&vals);
    if !(v.is_finite() && v >= 1.0 && v.fract() == 0.0 && v <= 1e7) {
        return Err(format!("a count must be an integer in [1, 1e7], found {v}"));
    }
    Ok(v as usize)
}
