//! Content hashing of files with a persistent cache keyed by file identity.
//!
//! A file's hash is blake3 of its bytes, hex encoded. Large files are read in 1 MiB chunks
//! and each chunk is hashed with blake3's rayon-parallel tree (`update_rayon`); many files are
//! hashed in parallel across rayon workers. Hashes are remembered in `artifacts/hash-cache.json`
//! keyed by path and validated by (device, inode, size, mtime, ctime): the hash is recomputed
//! only when one of those changed. ctime cannot be set from user space, so even a file whose
//! mtime was restored after an edit is rehashed. The cache is only an accelerator: losing it
//! costs one rehash, and a stale entry cannot survive a change of any of the five keys.

use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::io::Read;
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// Chunk size for reading large files: 1024 blake3 chunks, enough for its rayon tree to pay
/// off, and small enough to stay in cache between the `read` copy and the hash.
const CHUNK: usize = 1 << 20;
/// Below this size a file is hashed on one thread (the rayon split costs more than it saves).
const PARALLEL_MIN: u64 = 1 << 20;

/// The identity of a file's current content as the kernel sees it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Stamp {
    dev: u64,
    ino: u64,
    size: u64,
    mtime_ns: i128,
    ctime_ns: i128,
}

impl Stamp {
    /// The stamp of a file's metadata.
    pub fn of(meta: &std::fs::Metadata) -> Self {
        Self {
            dev: meta.dev(),
            ino: meta.ino(),
            size: meta.size(),
            mtime_ns: meta.mtime() as i128 * 1_000_000_000 + meta.mtime_nsec() as i128,
            ctime_ns: meta.ctime() as i128 * 1_000_000_000 + meta.ctime_nsec() as i128,
        }
    }
}

#[derive(Debug, Clone, Serialize, Deserialize)]
struct Entry {
    stamp: Stamp,
    blake3: String,
}

/// Hashes a whole file (no cache).
pub fn hash_file(path: &Path) -> Result<(String, u64)> {
    let mut f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let size = f.metadata().map_err(|e| Error::io(path, e))?.len();
    let mut hasher = blake3::Hasher::new();
    if size < PARALLEL_MIN {
        let mut buf = Vec::with_capacity(size as usize);
        f.read_to_end(&mut buf).map_err(|e| Error::io(path, e))?;
        hasher.update(&buf);
        return Ok((hasher.finalize().to_hex().to_string(), buf.len() as u64));
    }
    let mut buf = vec![0u8; CHUNK];
    let mut total = 0u64;
    loop {
        // Fill the whole chunk so that every update_rayon call gets a large slice.
        let mut filled = 0;
        while filled < CHUNK {
            let n = f.read(&mut buf[filled..]).map_err(|e| Error::io(path, e))?;
            if n == 0 {
                break;
            }
            filled += n;
        }
        if filled == 0 {
            break;
        }
        hasher.update_rayon(&buf[..filled]);
        total += filled as u64;
        if filled < CHUNK {
            break;
        }
    }
    Ok((hasher.finalize().to_hex().to_string(), total))
}

/// The persistent (path -> stamp, hash) cache.
#[derive(Debug, Default)]
pub struct HashCache {
    path: Option<PathBuf>,
    entries: Mutex<BTreeMap<String, Entry>>,
    dirty: Mutex<bool>,
    hashed_bytes: std::sync::atomic::AtomicU64,
}

/// A file's cached or computed hash.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FileHash {
    /// Hex blake3 of the content.
    pub blake3: String,
    /// Size in bytes.
    pub size: u64,
}

impl HashCache {
    /// Loads the cache file (a missing or unreadable cache is an empty cache).
    pub fn load(path: &Path) -> Self {
        let entries = std::fs::read(path)
            .ok()
            .and_then(|b| serde_json::from_slice(&b).ok())
            .unwrap_or_default();
        Self {
            path: Some(path.to_owned()),
            entries: Mutex::new(entries),
            ..Self::default()
        }
    }

    /// The hash of `path`, from the cache when its stamp is unchanged.
    pub fn hash(&self, path: &Path) -> Result<FileHash> {
        let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
        let stamp = Stamp::of(&meta);
        let key = path.to_string_lossy().into_owned();
        if let Some(e) = self.lock_entries().get(&key) {
            if e.stamp == stamp {
                return Ok(FileHash {
                    blake3: e.blake3.clone(),
                    size: stamp.size,
                });
            }
        }
        let (blake3, _) = hash_file(path)?;
        self.hashed_bytes
            .fetch_add(stamp.size, std::sync::atomic::Ordering::Relaxed);
        // Re-stat: a file that changed while being read must not be cached under the new stamp.
        let after = std::fs::metadata(path).map(|m| Stamp::of(&m)).ok();
        if after == Some(stamp) {
            self.lock_entries().insert(
                key,
                Entry {
                    stamp,
                    blake3: blake3.clone(),
                },
            );
            *self.dirty.lock().unwrap_or_else(|e| e.into_inner()) = true;
        }
        Ok(FileHash {
            blake3,
            size: stamp.size,
        })
    }

    /// Records a hash computed elsewhere (for a file just moved into the store) under the
    /// file's current stamp.
    pub fn insert(&self, path: &Path, stamp: Stamp, blake3: String) {
        self.lock_entries()
            .insert(path.to_string_lossy().into_owned(), Entry { stamp, blake3 });
        *self.dirty.lock().unwrap_or_else(|e| e.into_inner()) = true;
    }

    /// Hashes many files in parallel, results in input order.
    pub fn hash_all(&self, paths: &[PathBuf]) -> Vec<Result<FileHash>> {
        use rayon::prelude::*;
        paths.par_iter().map(|p| self.hash(p)).collect()
    }

    /// Bytes actually read and hashed (cache misses) since load.
    pub fn hashed_bytes(&self) -> u64 {
        self.hashed_bytes.load(std::sync::atomic::Ordering::Relaxed)
    }

    /// Forgets every entry under `dir` (its files are being deleted).
    pub fn forget_under(&self, dir: &Path) {
        let prefix = dir.to_string_lossy().into_owned();
        let mut entries = self.lock_entries();
        let before = entries.len();
        entries.retain(|k, _| !k.starts_with(&prefix));
        if entries.len() != before {
            *self.dirty.lock().unwrap_or_else(|e| e.into_inner()) = true;
        }
    }

    /// Writes the cache back (atomically) if it changed.
    pub fn save(&self) -> Result<()> {
        let Some(path) = &self.path else {
            return Ok(());
        };
        let mut dirty = self.dirty.lock().unwrap_or_else(|e| e.into_inner());
        if !*dirty {
            return Ok(());
        }
        let entries = self.lock_entries();
        // Drop entries whose file is gone, so the cache does not grow without bound.
        let live: BTreeMap<&String, &Entry> = entries
            .iter()
            .filter(|(k, _)| Path::new(k).exists())
            .collect();
        let bytes = serde_json::to_vec(&live).expect("serialisable");
        atomic_file::write_atomic(path, &bytes)?;
        *dirty = false;
        Ok(())
    }

    fn lock_entries(&self) -> std::sync::MutexGuard<'_, BTreeMap<String, Entry>> {
        self.entries.lock().unwrap_or_else(|e| e.into_inner())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cache_hits_until_the_file_changes() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("a");
        std::fs::write(&f, b"hello").unwrap();
        let cache = HashCache::load(&dir.path().join("cache.json"));
        let h1 = cache.hash(&f).unwrap();
        assert_eq!(h1.blake3, blake3::hash(b"hello").to_hex().to_string());
        assert_eq!(cache.hashed_bytes(), 5);
        assert_eq!(cache.hash(&f).unwrap(), h1);
        assert_eq!(
            cache.hashed_bytes(),
            5,
            "second lookup must come from the cache"
        );
        cache.save().unwrap();
        // Same size, new content: the ctime/mtime stamp changes, so it is rehashed.
        std::fs::write(&f, b"jello").unwrap();
        let cache = HashCache::load(&dir.path().join("cache.json"));
        let h2 = cache.hash(&f).unwrap();
        assert_eq!(h2.blake3, blake3::hash(b"jello").to_hex().to_string());
        assert_eq!(cache.hashed_bytes(), 5);
    }

    #[test]
    fn chunked_parallel_hash_equals_one_shot() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("big");
        // Two full chunks and a partial one exercise the chunk loop's boundaries.
        let data: Vec<u8> = (0..(2 * CHUNK + 12345))
            .map(|i| (i * 31 % 251) as u8)
            .collect();
        std::fs::write(&f, &data).unwrap();
        let (h, n) = hash_file(&f).unwrap();
        assert_eq!(n, data.len() as u64);
        assert_eq!(h, blake3::hash(&data).to_hex().to_string());
    }
}
