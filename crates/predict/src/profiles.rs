//! The profile points under the system for a prediction: read from a profile file (the
//! `irregularity` artifact) or generated as `irregularity` generates them.

use crate::Error;
use crate::Result;
use mbd_engine::Profile;
use mbd_system::System;
use pino_data::{schema, Table};
use std::collections::BTreeMap;
use std::path::Path;

/// Where the profile points under the system come from.
#[derive(Debug, Clone, PartialEq)]
pub enum ProfileChoice {
    /// A Parquet file with columns `x`, `eta` (m), optionally `sample_id` (the rows of the given
    /// id, else of the first) and `profile` (the rows of each generated profile by name).
    File {
        /// The file.
        path: std::path::PathBuf,
        /// The sample whose rows are used.
        sample_id: Option<i64>,
    },
    /// Generated as `irregularity` generates them, with the model's dataset's spacing and
    /// length and this seed and sample id.
    Generated {
        /// Seed of the random phases.
        seed: u64,
        /// Sample id of the stream.
        id: u64,
    },
}

/// The points of each generated profile of `system` (`None` for analytic ones), from `choice`;
/// `settings` are the dataset's generator controls (needed to generate).
pub fn profiles(
    system: &System,
    settings: Option<&mbd_dataset::ProfileParams>,
    choice: Option<&ProfileChoice>,
) -> Result<Vec<Option<Profile>>> {
    let generated = generated_names(system);
    if generated.is_empty() {
        return Ok(vec![None; system.profiles.len()]);
    }
    let flag = Path::new(PROFILE_FLAGS);
    match choice {
        None => Err(Error::format(
            flag,
            format!(
                "the system `{}` has generated profile(s) {}: give their points (--profile FILE) or a seed to generate them (--seed N)",
                system.name,
                generated.join(", ")
            ),
        )),
        Some(ProfileChoice::Generated { seed, id }) => {
            let base = settings.ok_or_else(|| {
                Error::format(
                    flag,
                    "the model's dataset records no profile settings (run.json): give --profile FILE".into(),
                )
            })?;
            GeneratedProfiles::new(system, base, *seed)?.of(*id)
        }
        Some(ProfileChoice::File { path, sample_id }) => {
            read_profiles(system, path, *sample_id, &generated)
        }
    }
}

/// Where errors about a prediction's profile points are blamed (`predict`'s flags).
const PROFILE_FLAGS: &str = "--profile / --seed";

/// The generators of a system's profiles at one seed, built once: the profiles of any
/// sample id (a study draws thousands), as `irregularity` generates them.
pub struct GeneratedProfiles {
    pub(super) generators: Vec<Option<mbd_dataset::ProfileGenerator>>,
    /// What the caller calls the excitation (`predict`'s flags, the Python package's
    /// `excitation`), which its refusals blame.
    pub(super) what: String,
}

impl GeneratedProfiles {
    /// The generators of `system`'s profiles with the dataset's `settings` and `seed`, their
    /// refusals blamed on `predict`'s flags.
    pub fn new(system: &System, settings: &mbd_dataset::ProfileParams, seed: u64) -> Result<Self> {
        Self::named(system, settings, seed, PROFILE_FLAGS)
    }

    /// [`GeneratedProfiles::new`], its refusals blamed on `what` (the caller's name for the
    /// excitation).
    pub fn named(
        system: &System,
        settings: &mbd_dataset::ProfileParams,
        seed: u64,
        what: &str,
    ) -> Result<Self> {
        let params = mbd_dataset::ProfileParams { seed, ..*settings };
        let generators = mbd_dataset::profile_generators(system, &params)
            .map_err(|e| Error::format(Path::new(what), e.to_string()))?;
        Ok(Self {
            generators,
            what: what.to_owned(),
        })
    }

    /// The points of each profile (`None` for analytic ones) of sample `id`.
    pub fn of(&self, id: u64) -> Result<Vec<Option<Profile>>> {
        self.generators
            .iter()
            .map(|g| {
                g.as_ref()
                    .map(|g| Profile::new(g.positions(), g.profile(id)))
                    .transpose()
                    .map_err(|e| Error::format(Path::new(&self.what), e.to_string()))
            })
            .collect()
    }
}

pub(super) fn generated_names(system: &System) -> Vec<&str> {
    system
        .profiles
        .iter()
        .filter(|p| matches!(p, mbd_system::system::Profile::Generated { .. }))
        .map(|p| p.name())
        .collect()
}

/// The profiles of each of samples `ids` from profile files (the `irregularity` artifact),
/// read once; see [`ProfileChoice::File`].
pub fn profiles_of_samples(
    system: &System,
    files: &[std::path::PathBuf],
    ids: &[i64],
) -> Result<BTreeMap<i64, Vec<Option<Profile>>>> {
    if generated_names(system).is_empty() {
        // Nothing to read: every profile is analytic.
        return profiles_of_table(system, &Table::default(), Path::new("profiles"), ids);
    }
    let t = pino_data::read_parquet_files(files, None)?;
    let path = files.first().map_or(Path::new("profiles"), |p| p.as_path());
    profiles_of_table(system, &t, path, ids)
}

/// The profiles of each of samples `ids` from a profile table `t` (columns `sample_id`, `x`,
/// `eta` and, with several generated profiles, `profile`), read from `path` (named in errors);
/// see [`profiles_of_samples`].
pub fn profiles_of_table(
    system: &System,
    t: &Table,
    path: &Path,
    ids: &[i64],
) -> Result<BTreeMap<i64, Vec<Option<Profile>>>> {
    let generated = generated_names(system);
    if generated.is_empty() {
        return Ok(ids
            .iter()
            .map(|&id| (id, vec![None; system.profiles.len()]))
            .collect());
    }
    // The rows of each sample, in one pass over the table.
    let mut rows: BTreeMap<i64, Vec<usize>> = ids.iter().map(|&id| (id, Vec::new())).collect();
    for (r, id) in t.i64(schema::SAMPLE_ID)?.iter().enumerate() {
        if let Some(rows) = rows.get_mut(id) {
            rows.push(r);
        }
    }
    rows.into_iter()
        .map(|(id, rows)| {
            let p = profiles_of_rows(system, t, path, &rows, Some(id), &generated)?;
            Ok((id, p))
        })
        .collect()
}

fn read_profiles(
    system: &System,
    path: &Path,
    sample_id: Option<i64>,
    generated: &[&str],
) -> Result<Vec<Option<Profile>>> {
    let t = pino_data::read_parquet(path, None)?;
    let ids = t.i64(schema::SAMPLE_ID).ok();
    let id = match (ids, sample_id) {
        (Some(_), Some(id)) => Some(id),
        (Some(ids), None) => ids.first().copied(),
        (None, _) => None,
    };
    let rows: Vec<usize> = (0..t.num_rows())
        .filter(|&r| ids.is_none_or(|ids| Some(ids[r]) == id))
        .collect();
    profiles_of_rows(system, &t, path, &rows, id, generated)
}

/// The generated profiles of one sample from its `rows` of a profile table (`id` names it in
/// messages).
fn profiles_of_rows(
    system: &System,
    t: &Table,
    path: &Path,
    rows: &[usize],
    id: Option<i64>,
    generated: &[&str],
) -> Result<Vec<Option<Profile>>> {
    let x = t.f64(schema::TRACK_X)?;
    let eta = t.f64(schema::TRACK_ETA)?;
    let names = t.str(PROFILE_COLUMN).ok();
    if names.is_none() && generated.len() > 1 {
        return Err(Error::format(
            path,
            format!(
                "no `{PROFILE_COLUMN}` column, but the system `{}` has {} generated profiles ({}): label the rows by profile",
                system.name,
                generated.len(),
                generated.join(", ")
            ),
        ));
    }
    system
        .profiles
        .iter()
        .map(|p| {
            if !matches!(p, mbd_system::system::Profile::Generated { .. }) {
                return Ok(None);
            }
            let rows: Vec<usize> = rows
                .iter()
                .copied()
                .filter(|&r| names.is_none_or(|n| n[r] == p.name()))
                .collect();
            if rows.is_empty() {
                let which = id.map_or("in the table".to_owned(), |id| {
                    format!("for sample_id {id}")
                });
                return Err(Error::format(
                    path,
                    format!("no rows of profile `{}` {which}", p.name()),
                ));
            }
            Profile::new(
                rows.iter().map(|&r| x[r]).collect(),
                rows.iter().map(|&r| eta[r]).collect(),
            )
            .map(Some)
            .map_err(|e| Error::format(path, format!("profile `{}`: {e}", p.name())))
        })
        .collect()
}

/// The column of a profile file naming each row's profile (written by `irregularity` when a
/// description has several).
pub const PROFILE_COLUMN: &str = pino_data::schema::PROFILE;

/// The profile points under each design of a batch: one set for all, or each design's own
/// (by its position in the batch's list of designs).
pub enum ProfileSource<'a> {
    /// The same profiles under every design.
    Shared(&'a [Option<Profile>]),
    /// The profiles of design `k`.
    PerDesign(&'a (dyn Fn(usize) -> Result<Vec<Option<Profile>>> + Sync)),
}
