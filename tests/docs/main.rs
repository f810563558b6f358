//! The user documentation against the workspace: the README's layout table lists every
//! workspace member and every shipped pipeline file and nothing that is not there; the
//! relative links of README.md, BENCHMARKS.md and docs/ point at files that exist.

mod layout;
mod links;
