//! Where prepared samples' time series live: in memory, or spilled to an unlinked temporary
//! file when they would exceed a memory budget.
//!
//! Each sample is one fixed-size record ([`SeriesShape`]): z-scored f32 outputs `[T, O]`,
//! velocities and accelerations `[T, D]`, then the physical f64 excitations `[T, E]`. Records are appended
//! in the order they are read and addressed by slot. In memory they sit in four contiguous
//! vectors. Past the budget (`PINO_DATA_MEMORY_MB`, default 4096 MiB, checked against the
//! expected sample count before the first record), every record goes to a file created in
//! `PINO_DATA_SPILL_DIR` (default: the system temporary directory, which must be on disk, not
//! a RAM file system) and removed from the directory at once, so it disappears with the
//! process however it ends; a batch reads its records back with positioned reads. The
//! operating system's page cache then keeps hot records in otherwise free memory without
//! counting them in the process's resident set, and the values read back are bitwise those
//! written.

use crate::layout::SeriesShape;
use crate::{io_err, Result};
use std::fs::File;
use std::os::unix::fs::FileExt;
use std::path::PathBuf;

/// One sample's series, owned.
#[derive(Debug, Clone, PartialEq)]
pub struct SampleSeries {
    /// z-scored outputs `[T, O]`.
    pub u: Vec<f32>,
    /// z-scored velocities `[T, D]`.
    pub v: Vec<f32>,
    /// z-scored accelerations `[T, D]`.
    pub a: Vec<f32>,
    /// Excitations `[T, E]` (m).
    pub eta: Vec<f64>,
}

#[derive(Debug)]
enum Backend {
    Memory {
        u: Vec<f32>,
        v: Vec<f32>,
        a: Vec<f32>,
        eta: Vec<f64>,
    },
    File {
        file: File,
        path: PathBuf,
    },
}

/// Fixed-size records of `T` points each (see the module doc).
#[derive(Debug)]
pub struct SeriesStore {
    tp: usize,
    shape: SeriesShape,
    len: usize,
    backend: Backend,
}

/// Default memory budget of a store (MiB).
pub const DEFAULT_BUDGET_MB: usize = 4096;

fn budget_bytes() -> usize {
    std::env::var("PINO_DATA_MEMORY_MB")
        .ok()
        .and_then(|v| v.trim().parse::<usize>().ok())
        .unwrap_or(DEFAULT_BUDGET_MB)
        .saturating_mul(1 << 20)
}

impl SeriesStore {
    /// Bytes of one record of `tp` points.
    pub fn record_bytes(tp: usize, shape: SeriesShape) -> usize {
        tp * (4 * (shape.outputs + 2 * shape.dofs) + 8 * shape.excitations)
    }

    /// A store for about `expected` records of `tp` points: in memory when they fit the
    /// budget, else in a spill file.
    pub fn new(tp: usize, shape: SeriesShape, expected: usize) -> Result<Self> {
        let backend = if expected.saturating_mul(Self::record_bytes(tp, shape)) <= budget_bytes() {
            Backend::Memory {
                u: Vec::with_capacity(expected * tp * shape.outputs),
                v: Vec::with_capacity(expected * tp * shape.dofs),
                a: Vec::with_capacity(expected * tp * shape.dofs),
                eta: Vec::with_capacity(expected * tp * shape.excitations),
            }
        } else {
            let dir = std::env::var_os("PINO_DATA_SPILL_DIR")
                .map(PathBuf::from)
                .unwrap_or_else(std::env::temp_dir);
            static COUNTER: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
            let n = COUNTER.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            let path = dir.join(format!(".pino-samples-{}-{n}.f32", std::process::id()));
            let file = std::fs::OpenOptions::new()
                .read(true)
                .write(true)
                .create_new(true)
                .open(&path)
                .map_err(|e| io_err(&path, e))?;
            // Unlinked now: the open handle keeps the data until the process ends.
            std::fs::remove_file(&path).map_err(|e| io_err(&path, e))?;
            Backend::File { file, path }
        };
        Ok(Self {
            tp,
            shape,
            len: 0,
            backend,
        })
    }

    /// Whether the records are in a spill file.
    pub fn spilled(&self) -> bool {
        matches!(self.backend, Backend::File { .. })
    }

    /// Number of records.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Bytes of series held in memory.
    pub fn memory_bytes(&self) -> usize {
        match &self.backend {
            Backend::Memory { u, v, a, eta } => 4 * (u.len() + v.len() + a.len()) + 8 * eta.len(),
            Backend::File { .. } => 0,
        }
    }

    /// Appends one record; returns its slot.
    pub fn push(&mut self, s: &SampleSeries) -> Result<usize> {
        let (tp, sh) = (self.tp, self.shape);
        debug_assert_eq!(
            (s.u.len(), s.v.len(), s.a.len(), s.eta.len()),
            (
                tp * sh.outputs,
                tp * sh.dofs,
                tp * sh.dofs,
                tp * sh.excitations
            )
        );
        let slot = self.len;
        match &mut self.backend {
            Backend::Memory { u, v, a, eta } => {
                u.extend_from_slice(&s.u);
                v.extend_from_slice(&s.v);
                a.extend_from_slice(&s.a);
                eta.extend_from_slice(&s.eta);
            }
            Backend::File { file, path } => {
                let mut bytes = Vec::with_capacity(Self::record_bytes(tp, sh));
                for x in s.u.iter().chain(&s.v).chain(&s.a) {
                    bytes.extend_from_slice(&x.to_le_bytes());
                }
                for x in &s.eta {
                    bytes.extend_from_slice(&x.to_le_bytes());
                }
                file.write_all_at(&bytes, (slot * Self::record_bytes(tp, sh)) as u64)
                    .map_err(|e| io_err(path, e))?;
            }
        }
        self.len += 1;
        Ok(slot)
    }

    /// The record in `slot`.
    pub fn get(&self, slot: usize) -> Result<SampleSeries> {
        let (tp, sh) = (self.tp, self.shape);
        let (nu, nd, ne) = (tp * sh.outputs, tp * sh.dofs, tp * sh.excitations);
        match &self.backend {
            Backend::Memory { u, v, a, eta } => Ok(SampleSeries {
                u: u[slot * nu..(slot + 1) * nu].to_vec(),
                v: v[slot * nd..(slot + 1) * nd].to_vec(),
                a: a[slot * nd..(slot + 1) * nd].to_vec(),
                eta: eta[slot * ne..(slot + 1) * ne].to_vec(),
            }),
            Backend::File { file, path } => {
                let mut bytes = vec![0u8; Self::record_bytes(tp, sh)];
                file.read_exact_at(&mut bytes, (slot * Self::record_bytes(tp, sh)) as u64)
                    .map_err(|e| io_err(path, e))?;
                let (f32s, f64s) = bytes.split_at(4 * (nu + 2 * nd));
                let f: Vec<f32> = f32s
                    .chunks_exact(4)
                    .map(|b| f32::from_le_bytes(b.try_into().expect("4 bytes")))
                    .collect();
                Ok(SampleSeries {
                    u: f[..nu].to_vec(),
                    v: f[nu..nu + nd].to_vec(),
                    a: f[nu + nd..].to_vec(),
                    eta: f64s
                        .chunks_exact(8)
                        .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
                        .collect(),
                })
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SHAPE: SeriesShape = SeriesShape {
        outputs: 18,
        dofs: 10,
        excitations: 4,
    };

    fn series(tp: usize, k: usize) -> SampleSeries {
        let f = |n: usize, o: usize| -> Vec<f32> {
            (0..n).map(|i| (i * 7 + k * 13 + o) as f32 / 3.0).collect()
        };
        SampleSeries {
            u: f(tp * SHAPE.outputs, 0),
            v: f(tp * SHAPE.dofs, 1),
            a: f(tp * SHAPE.dofs, 2),
            eta: (0..tp * SHAPE.excitations)
                .map(|i| (i + k) as f64 * 1.1e-4)
                .collect(),
        }
    }

    #[test]
    fn memory_and_spill_file_hold_the_same_bits() {
        let tp = 5;
        let mut mem = SeriesStore::new(tp, SHAPE, 3).unwrap();
        assert!(!mem.spilled());
        // Far above any budget: a spill file.
        let mut file =
            SeriesStore::new(tp, SHAPE, usize::MAX / SeriesStore::record_bytes(tp, SHAPE)).unwrap();
        assert!(file.spilled() && file.memory_bytes() == 0);
        for k in 0..3 {
            assert_eq!(mem.push(&series(tp, k)).unwrap(), k);
            assert_eq!(file.push(&series(tp, k)).unwrap(), k);
        }
        assert_eq!((mem.len(), file.len()), (3, 3));
        assert_eq!(mem.memory_bytes(), 3 * SeriesStore::record_bytes(tp, SHAPE));
        for k in [2, 0, 1] {
            let want = series(tp, k);
            assert_eq!(mem.get(k).unwrap(), want);
            assert_eq!(file.get(k).unwrap(), want);
        }
    }
}
