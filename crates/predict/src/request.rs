//! What a `predict` request resolves to before anything is predicted: its designs (a list, a
//! sweep or the nominal design, with overrides, each checked against the description), the
//! profiles it asks for, and the warning about designs outside the training ranges.

use crate::design::DesignSpace;
use crate::profiles::ProfileChoice;
use crate::sweep::parse_sweep;
use crate::Result;
use pino_learn::checkpoint::OutOfRange;
use std::path::{Path, PathBuf};

/// Designs shown by name in [`outside_message`]; the rest are counted.
pub const OUTSIDE_SHOWN: usize = 5;

/// Where a request's designs come from.
#[derive(Debug, Clone, Copy)]
pub enum DesignSource<'a> {
    /// A list of designs: YAML text and the file it was read from.
    Sets(&'a str, &'a Path),
    /// A sweep ([`parse_sweep`]): YAML text and the file it was read from.
    Sweep(&'a str, &'a Path),
    /// The nominal design alone.
    Nominal,
}

impl DesignSpace {
    /// The designs of `source` with every `name=value` of `overrides` applied, each checked
    /// against the description (a refusal names `sets[k]`).
    pub fn designs(&self, source: DesignSource<'_>, overrides: &[String]) -> Result<Vec<Vec<f64>>> {
        let mut sets = match source {
            DesignSource::Sets(text, path) => self.parse_sets(text, path)?,
            DesignSource::Sweep(text, path) => parse_sweep(self, text, path)?,
            DesignSource::Nominal => vec![self.nominal()],
        };
        for s in overrides {
            self.apply_override(&mut sets, s)?;
        }
        for (k, s) in sets.iter().enumerate() {
            self.check(s, &format!("sets[{k}]"))?;
        }
        Ok(sets)
    }
}

impl ProfileChoice {
    /// The profiles a request asks for: a profile `file` (its rows of sample `id`), else
    /// generated with `seed` (stream `id`, 0 when absent), else none.
    pub fn of(file: Option<&Path>, seed: Option<u64>, id: Option<i64>) -> Option<Self> {
        match (file, seed) {
            (Some(path), _) => Some(ProfileChoice::File {
                path: PathBuf::from(path),
                sample_id: id,
            }),
            (None, Some(seed)) => Some(ProfileChoice::Generated {
                seed,
                id: id.unwrap_or(0) as u64,
            }),
            (None, None) => None,
        }
    }
}

/// The warning about the designs outside the training ranges (`outside`, per design, from
/// [`Predictor::outside_training`](crate::Predictor::outside_training); `source` names the
/// ranges' origin): how many, and the first [`OUTSIDE_SHOWN`] by name. `None` when every design
/// is inside.
pub fn outside_message(outside: &[Vec<OutOfRange>], source: &str) -> Option<String> {
    let flagged: Vec<usize> = (0..outside.len())
        .filter(|&k| !outside[k].is_empty())
        .collect();
    if flagged.is_empty() {
        return None;
    }
    let shown: Vec<String> = flagged
        .iter()
        .take(OUTSIDE_SHOWN)
        .map(|&k| {
            let what: Vec<String> = outside[k].iter().map(|o| o.to_string()).collect();
            format!("sets[{k}]: {}", what.join(", "))
        })
        .collect();
    Some(format!(
        "{} of {} set(s) outside the model's training ranges (from {source}), where its predictions are extrapolations: {}{}",
        flagged.len(),
        outside.len(),
        shown.join("; "),
        if flagged.len() > OUTSIDE_SHOWN { "; ..." } else { "" }
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use learn_fixtures::synthetic::vehicle_track_system;

    fn outside_of(value: f64) -> OutOfRange {
        OutOfRange {
            name: "m_c".into(),
            value,
            range: [0.0, 1.0],
        }
    }

    #[test]
    fn the_outside_message_counts_every_flagged_design_and_names_the_first_five() {
        let mut outside = vec![Vec::new(); 8];
        for (k, o) in outside.iter_mut().enumerate().skip(1) {
            o.push(outside_of(2.0 + k as f64));
        }
        let msg = outside_message(&outside, "params.parquet").unwrap();
        assert!(
            msg.starts_with("7 of 8 set(s) outside the model's training ranges (from params.parquet), where its predictions are extrapolations: sets[1]: m_c = 3 (trained on 0 .. 1); "),
            "{msg}"
        );
        assert!(
            msg.contains("sets[5]: m_c = 7") && !msg.contains("sets[6]"),
            "{msg}"
        );
        assert!(msg.ends_with("; ..."), "{msg}");
        outside.truncate(3);
        let msg = outside_message(&outside, "x").unwrap();
        assert!(
            msg.starts_with("2 of 3 set(s)") && msg.ends_with("m_c = 4 (trained on 0 .. 1)"),
            "{msg}"
        );
        assert_eq!(outside_message(&[Vec::new(), Vec::new()], "x"), None);
    }

    #[test]
    fn a_profile_file_wins_over_a_seed_and_a_generated_stream_defaults_to_sample_0() {
        let file = Path::new("profiles.parquet");
        let chosen = ProfileChoice::of(Some(file), Some(3), Some(7));
        assert!(
            matches!(&chosen, Some(ProfileChoice::File { path, sample_id: Some(7) }) if path == file),
            "{chosen:?}"
        );
        let chosen = ProfileChoice::of(None, Some(3), None);
        assert!(
            matches!(chosen, Some(ProfileChoice::Generated { seed: 3, id: 0 })),
            "{chosen:?}"
        );
        assert!(ProfileChoice::of(None, None, Some(2)).is_none());
    }

    #[test]
    fn designs_take_overrides_on_every_set_and_refuse_a_bad_one_by_its_place() {
        let space = DesignSpace::of(vehicle_track_system());
        let o = Path::new("sets.yaml");
        let m_c = space.index("m_c", o).unwrap();
        let nominal = space.nominal();
        let sets = space.designs(DesignSource::Nominal, &[]).unwrap();
        assert_eq!(sets, vec![nominal.clone()]);
        let text = "- {k_s: 4.0e5}\n- {}\n";
        let over = ["l_c=8.5".to_owned()];
        let sets = space.designs(DesignSource::Sets(text, o), &over).unwrap();
        let l_c = space.index("l_c", o).unwrap();
        assert_eq!(sets.len(), 2);
        assert!(sets.iter().all(|s| s[l_c] == 8.5));
        assert_eq!(sets[1][m_c], nominal[m_c]);
        let sweep = "grid: {m_c: [30000, 40000, 50000]}\n";
        let sets = space.designs(DesignSource::Sweep(sweep, o), &[]).unwrap();
        assert_eq!(
            sets.iter().map(|s| s[m_c]).collect::<Vec<_>>(),
            [3e4, 4e4, 5e4]
        );
        let err = space
            .designs(DesignSource::Sets(text, o), &["m_c=-1".to_owned()])
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with("`sets[0].m_c` = -1 is out of range"),
            "{err}"
        );
    }
}
