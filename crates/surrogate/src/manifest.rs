//! `surrogate.json`: what a surrogate is made of and which model answers what.
//!
//! A surrogate directory holds the manifest and, under `members/<name>/`, each chosen model's
//! `model.json`, `model.safetensors` and `calibration.json`, copied: the directory is the whole
//! artifact (move it, open it elsewhere). The manifest records every candidate that was
//! considered (its identity, the hashes of its files), the members, and per index and per
//! channel the member that answers it with every candidate's validation error beside it. A
//! member's files are verified against their hashes on load.

use crate::Error;
use crate::Result;
use pino_calibration::{short, DesignIdentity, ModelIdentity, CALIBRATION_FILE, MODEL_WEIGHTS};
use pino_learn::checkpoint::MODEL_META;
use pino_learn::Error as LearnError;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The manifest's file name.
pub const SURROGATE_FILE: &str = "surrogate.json";

/// Its format tag.
pub const SURROGATE_FORMAT: &str = "pino-mbd surrogate 1";

/// The directory of the members' files.
pub const MEMBERS_DIR: &str = "members";

/// The files of a member, as copied from its model and calibration.
pub const MEMBER_FILES: [&str; 3] = [MODEL_META, MODEL_WEIGHTS, CALIBRATION_FILE];

/// A model that was considered.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Candidate {
    /// Its name in the routes (its label, made unique among the candidates).
    pub name: String,
    /// Its identity (the hash of its files).
    pub model: ModelIdentity,
}

/// A chosen model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Member {
    /// Its candidate name.
    pub name: String,
    /// Its identity.
    pub model: ModelIdentity,
    /// blake3 of its `calibration.json`, hex.
    pub calibration_blake3: String,
}

/// Which member answers a quantity, and how every candidate did on it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Route {
    /// The index or channel.
    pub name: String,
    /// Its unit.
    pub unit: String,
    /// The member answering it.
    pub member: String,
    /// Per candidate (by name) that has the quantity: its mean relative error on the validation
    /// split (%), or its mean absolute error where no relative error is defined.
    pub validation: BTreeMap<String, f64>,
    /// What `validation` holds: `mean_relative_pct` or `mean_abs`.
    pub metric: String,
}

/// `surrogate.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// [`SURROGATE_FORMAT`].
    pub format: String,
    /// The system's name.
    pub system: String,
    /// The dataset design every candidate was trained and calibrated on.
    pub design: DesignIdentity,
    /// Validation samples the choice was made on.
    pub n_validation: usize,
    /// Every candidate, in the order given.
    pub candidates: Vec<Candidate>,
    /// The chosen ones, in candidate order.
    pub members: Vec<Member>,
    /// Per index of the description, in its order.
    pub indices: Vec<Route>,
    /// Per predicted channel (outputs, then the rigid DOFs' velocities and accelerations,
    /// then rate outputs), in the primary member's order.
    pub channels: Vec<Route>,
}

impl Manifest {
    /// The member answering the most indices (ties: the first): the one whose system, design
    /// space, time grid and channel order a surrogate presents ([`super::Surrogate::primary`]).
    pub fn primary(&self) -> usize {
        let index_member: Vec<usize> = self
            .indices
            .iter()
            .map(|r| {
                self.members
                    .iter()
                    .position(|m| m.name == r.member)
                    .unwrap_or(0)
            })
            .collect();
        super::primary_of(&index_member, self.members.len())
    }

    /// The directory of member `name` under the surrogate's directory `dir`.
    pub fn member_dir(dir: &Path, name: &str) -> PathBuf {
        dir.join(MEMBERS_DIR).join(name)
    }

    /// Reads and checks `dir/surrogate.json` (format, members named by the routes), and
    /// verifies every member's files against their recorded hashes.
    pub fn load(dir: &Path) -> Result<Self> {
        let file = dir.join(SURROGATE_FILE);
        if !file.is_file() {
            return Err(Error::format(
                &file,
                "no surrogate here: a surrogate is the directory the `surrogate` stage writes (`pipeline show surrogate`)".into(),
            ));
        }
        let text = std::fs::read_to_string(&file).map_err(|e| LearnError::Io {
            path: file.clone(),
            source: e,
        })?;
        let m: Manifest = serde_json::from_str(&text)
            .map_err(|e| Error::format(&file, format!("not a surrogate manifest: {e}")))?;
        if m.format != SURROGATE_FORMAT {
            return Err(Error::format(
                &file,
                format!("format `{}`, expected `{SURROGATE_FORMAT}`", m.format),
            ));
        }
        if m.members.is_empty() {
            return Err(Error::format(&file, "names no member model".into()));
        }
        for r in m.indices.iter().chain(&m.channels) {
            if !m.members.iter().any(|x| x.name == r.member) {
                return Err(Error::format(
                    &file,
                    format!(
                        "`{}` is routed to `{}`, which is not a member",
                        r.name, r.member
                    ),
                ));
            }
        }
        for member in &m.members {
            m.verify(dir, member)?;
        }
        Ok(m)
    }

    /// A member's files are the ones the surrogate was built with.
    fn verify(&self, dir: &Path, member: &Member) -> Result<()> {
        let at = Self::member_dir(dir, &member.name);
        let rebuild = "rebuild the surrogate (`pipeline run surrogate`)";
        let identity = ModelIdentity::of(&at).map_err(|e| {
            Error::format(
                &at,
                format!(
                    "member model `{}` cannot be read ({e}): {rebuild}",
                    member.name
                ),
            )
        })?;
        if identity.blake3 != member.model.blake3 {
            return Err(Error::format(
                &at.join(MODEL_WEIGHTS),
                format!(
                    "member model `{}` changed since the surrogate was built (blake3 {}, built with {}): {rebuild}",
                    member.name,
                    short(&identity.blake3),
                    short(&member.model.blake3)
                ),
            ));
        }
        let cal = at.join(CALIBRATION_FILE);
        let hash = file_blake3(&cal)?;
        if hash != member.calibration_blake3 {
            return Err(Error::format(
                &cal,
                format!(
                    "the calibration of member model `{}` changed since the surrogate was built (blake3 {}, built with {}): {rebuild}",
                    member.name,
                    short(&hash),
                    short(&member.calibration_blake3)
                ),
            ));
        }
        Ok(())
    }

    /// Writes `dir/surrogate.json` (atomically).
    pub fn write(&self, dir: &Path) -> Result<()> {
        let path = dir.join(SURROGATE_FILE);
        let text =
            serde_json::to_string_pretty(self).map_err(|e| Error::format(&path, e.to_string()))?;
        Ok(atomic_file::write_atomic(&path, text.as_bytes())?)
    }
}

/// blake3 of a file's bytes, hex.
pub fn file_blake3(path: &Path) -> Result<String> {
    let bytes = std::fs::read(path).map_err(|e| LearnError::Io {
        path: path.to_owned(),
        source: e,
    })?;
    Ok(blake3::hash(&bytes).to_hex().to_string())
}
