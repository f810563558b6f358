//! Per-stage `resources:` (what a Slurm job asks for): cpus, memory, time limit, GPUs,
//! partition, and extra `sbatch` arguments passed through as written.
//!
//! The block is parsed strictly (an unknown key is bad input at its line) and checked for
//! values `sbatch` would reject or that would break the stage protocol (`--array`, `--chdir`
//! and the output options belong to the orchestrator). Resources are not part of a unit's
//! identity: where a stage runs does not change what it computes. The local executor ignores
//! them.

use serde::{Deserialize, Deserializer};

/// What one unit's Slurm job asks for. Every field is optional; unset means the cluster's
/// default (one CPU, the partition's default memory and time limit, no GPU).
#[derive(Debug, Clone, Default, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Resources {
    /// CPUs per task (`--cpus-per-task`).
    #[serde(default)]
    pub cpus: Option<u32>,
    /// Memory per node (`--mem`): an integer (MB) or a number with a K/M/G/T suffix.
    #[serde(default, deserialize_with = "text_or_int")]
    pub mem: Option<String>,
    /// Time limit (`--time`): minutes, or `[days-]hours:minutes:seconds`.
    #[serde(default, deserialize_with = "text_or_int")]
    pub time: Option<String>,
    /// GPUs per job (`--gpus`); 0 or unset asks for none.
    #[serde(default)]
    pub gpus: Option<u32>,
    /// Partition (`--partition`).
    #[serde(default)]
    pub partition: Option<String>,
    /// Further `sbatch` arguments, passed as written after the ones above (so they win).
    #[serde(default)]
    pub sbatch_args: Vec<String>,
}

/// Options the orchestrator sets itself; a stage may not override them.
const RESERVED: &[&str] = &[
    "--array",
    "-a",
    "--chdir",
    "-D",
    "--output",
    "-o",
    "--error",
    "-e",
    "--parsable",
    "--wrap",
    "--job-name",
    "-J",
];

fn text_or_int<'de, D: Deserializer<'de>>(d: D) -> Result<Option<String>, D::Error> {
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum TextOrInt {
        Int(u64),
        Text(String),
    }
    Ok(Option::<TextOrInt>::deserialize(d)?.map(|v| match v {
        TextOrInt::Int(i) => i.to_string(),
        TextOrInt::Text(s) => s,
    }))
}

impl Resources {
    /// Checks the values; the message names the key and what is allowed.
    pub fn check(&self) -> Result<(), String> {
        if self.cpus == Some(0) {
            return Err("resources.cpus must be at least 1".into());
        }
        if let Some(m) = &self.mem {
            let digits = m.trim_end_matches(['K', 'M', 'G', 'T']);
            if digits.is_empty()
                || !digits.bytes().all(|b| b.is_ascii_digit())
                || m.len() - digits.len() > 1
            {
                return Err(format!(
                    "resources.mem `{m}`: expected megabytes or a number with a K, M, G or T suffix (e.g. 4G)"
                ));
            }
        }
        if let Some(t) = &self.time {
            let ok = !t.is_empty()
                && t.bytes()
                    .all(|b| b.is_ascii_digit() || b == b':' || b == b'-')
                && t.as_bytes()[0].is_ascii_digit();
            if !ok {
                return Err(format!(
                    "resources.time `{t}`: expected minutes or [days-]hours:minutes:seconds (e.g. 2:00:00)"
                ));
            }
        }
        if let Some(p) = &self.partition {
            let ok = !p.is_empty()
                && p.chars()
                    .all(|c| c.is_ascii_alphanumeric() || "_-.,".contains(c));
            if !ok {
                return Err(format!(
                    "resources.partition `{p}`: expected a partition name (letters, digits, `_-.,`)"
                ));
            }
        }
        for a in &self.sbatch_args {
            if !a.starts_with('-') {
                return Err(format!(
                    "resources.sbatch_args: `{a}` is not an option; write each as one `--name=value` item"
                ));
            }
            let name = a.split('=').next().unwrap_or(a);
            let short = name.len() == 2 && !name.starts_with("--");
            if RESERVED.contains(&name) || (short && RESERVED.contains(&&a[..2])) {
                return Err(format!(
                    "resources.sbatch_args: `{a}` is set by the orchestrator (array, working directory, output files, job name)"
                ));
            }
        }
        Ok(())
    }

    /// The `sbatch` options these resources stand for, extra arguments last.
    pub fn sbatch_options(&self) -> Vec<String> {
        let mut v = vec![format!("--cpus-per-task={}", self.cpus.unwrap_or(1))];
        if let Some(m) = &self.mem {
            v.push(format!("--mem={m}"));
        }
        if let Some(t) = &self.time {
            v.push(format!("--time={t}"));
        }
        if let Some(g) = self.gpus.filter(|&g| g > 0) {
            v.push(format!("--gpus={g}"));
        }
        if let Some(p) = &self.partition {
            v.push(format!("--partition={p}"));
        }
        v.extend(self.sbatch_args.iter().cloned());
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(yaml: &str) -> Result<Resources, String> {
        let r: Resources = serde_yaml::from_str(yaml).map_err(|e| e.to_string())?;
        r.check()?;
        Ok(r)
    }

    #[test]
    fn options_in_order_with_extras_last() {
        let r = parse("{cpus: 4, mem: 8G, time: '2:00:00', gpus: 1, partition: gpu, sbatch_args: ['--qos=long', '--exclusive']}").unwrap();
        assert_eq!(
            r.sbatch_options(),
            [
                "--cpus-per-task=4",
                "--mem=8G",
                "--time=2:00:00",
                "--gpus=1",
                "--partition=gpu",
                "--qos=long",
                "--exclusive"
            ]
        );
        let d = Resources::default();
        assert_eq!(d.sbatch_options(), ["--cpus-per-task=1"]);
        // Integers are accepted for memory (MB) and time (minutes).
        let r = parse("{mem: 4000, time: 30}").unwrap();
        assert_eq!(r.mem.as_deref(), Some("4000"));
        assert_eq!(r.time.as_deref(), Some("30"));
    }

    #[test]
    fn bad_values_are_refused_with_the_key() {
        for (yaml, word) in [
            ("{cpus: 0}", "cpus"),
            ("{mem: lots}", "mem"),
            ("{mem: 4GG}", "mem"),
            ("{time: soon}", "time"),
            ("{partition: 'a b'}", "partition"),
            ("{sbatch_args: ['qos=x']}", "sbatch_args"),
            ("{sbatch_args: ['--array=1-3']}", "orchestrator"),
            ("{sbatch_args: ['-o', 'x']}", "orchestrator"),
            ("{sbatch_args: ['--output=x']}", "orchestrator"),
        ] {
            let e = parse(yaml).unwrap_err();
            assert!(e.contains(word), "{yaml}: {e}");
        }
        let e = parse("{cpu: 2}").unwrap_err();
        assert!(e.contains("unknown field `cpu`"), "{e}");
    }
}
