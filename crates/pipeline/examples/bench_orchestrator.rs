//! Benchmark of the orchestrator's overhead: a 10-stage chain whose cached artifacts total
//! about 10 GB, timing `pipeline run` (everything cached) and `pipeline status`.
//!
//! ```text
//! cargo build --release -p pipeline --bin pipeline --example bench_orchestrator
//! target/release/examples/bench_orchestrator [--gb 10] [--stages 10] [--repeat 9] [--dir DIR]
//! ```
//!
//! The same executable is the stage: started with `PINO_STAGE_CONTEXT` set it follows the
//! stage protocol and creates `big.bin` (a sparse file of `mb` MiB) plus a few small files.
//! Sparse files cost no disk, but reading them costs what hashing costs (the kernel hands out
//! zero-filled pages through `read`), so the cold numbers measure reading + blake3 + rayon
//! honestly. Steps: (1) first run: executes the stages and hashes every output; (2) `status`
//! after deleting the hash cache, files still in the page cache: rehashes all 10 GB; (3) the
//! same after evicting the files from the page cache (`posix_fadvise(DONTNEED)`), the cold
//! case; (4) `run` and `status` repeated with the hash cache warm (one `stat` per file):
//! medians reported.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

fn stage_main(ctx_path: &Path) {
    let ctx: serde_json::Value =
        serde_json::from_slice(&std::fs::read(ctx_path).expect("context")).expect("json");
    let out = PathBuf::from(ctx["output"].as_str().expect("output"));
    let mb = ctx["params"]["mb"].as_u64().expect("mb");
    let index = ctx["params"]["index"].as_u64().expect("index");
    let big = std::fs::File::create(out.join("big.bin")).expect("create");
    big.set_len(mb << 20).expect("set_len");
    for k in 0..3 {
        std::fs::write(
            out.join(format!("part-{k}.txt")),
            format!("stage {index} part {k}\n"),
        )
        .expect("write");
    }
    println!("::summary {mb} MiB sparse");
}

/// Evicts every file under `dir` from the page cache (posix_fadvise DONTNEED), so the next
/// read goes back to the file system; affects only these files.
fn drop_page_cache(dir: &Path) {
    use std::os::fd::AsRawFd;
    for entry in std::fs::read_dir(dir).expect("read_dir") {
        let p = entry.expect("entry").path();
        if p.is_dir() {
            drop_page_cache(&p);
        } else if let Ok(f) = std::fs::File::open(&p) {
            // SAFETY: a valid open descriptor; fadvise only drops clean cached pages.
            unsafe { libc::posix_fadvise(f.as_raw_fd(), 0, 0, libc::POSIX_FADV_DONTNEED) };
        }
    }
}

fn median(mut v: Vec<Duration>) -> Duration {
    v.sort();
    v[v.len() / 2]
}

fn arg(args: &[String], name: &str) -> Option<String> {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1).cloned())
}

fn main() {
    if let Some(ctx) = std::env::var_os("PINO_STAGE_CONTEXT") {
        return stage_main(Path::new(&ctx));
    }
    let args: Vec<String> = std::env::args().collect();
    let gb: u64 = arg(&args, "--gb").map_or(10, |s| s.parse().expect("--gb N"));
    let stages: u64 = arg(&args, "--stages").map_or(10, |s| s.parse().expect("--stages N"));
    let repeat: usize = arg(&args, "--repeat").map_or(9, |s| s.parse().expect("--repeat N"));
    let me = std::env::current_exe().expect("own path");
    let examples = me.parent().expect("examples dir");
    let pipeline = examples.parent().expect("profile dir").join("pipeline");
    assert!(
        pipeline.is_file(),
        "build it first: cargo build --release -p pipeline --bin pipeline"
    );
    let tmp = match arg(&args, "--dir") {
        Some(d) => tempfile::tempdir_in(d),
        None => tempfile::tempdir(),
    }
    .expect("temp dir");
    let ws = tmp.path();
    let mb = gb * 1024 / stages;
    let mut yaml = String::from("stages:\n");
    for i in 0..stages {
        yaml.push_str(&format!(
            "  s{i}:\n    cmd: [{}]\n    params: {{index: {i}, mb: {mb}}}\n",
            me.file_name().unwrap().to_string_lossy()
        ));
        if i > 0 {
            yaml.push_str(&format!("    inputs: {{up: s{}}}\n", i - 1));
        }
    }
    std::fs::write(ws.join("pipeline.yaml"), yaml).expect("pipeline.yaml");
    let time = |cmd: &str| -> Duration {
        let t0 = Instant::now();
        let out = Command::new(&pipeline)
            .current_dir(ws)
            .args(["--bin-dir", &examples.to_string_lossy(), cmd])
            .output()
            .expect("pipeline");
        let took = t0.elapsed();
        assert!(
            out.status.success(),
            "pipeline {cmd} failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        took
    };
    println!(
        "workspace {}: {stages} stages x {mb} MiB = {:.1} GiB",
        ws.display(),
        (stages * mb) as f64 / 1024.0
    );
    let first = time("run");
    println!(
        "first run (execute + hash all outputs, cold): {:.2} s",
        first.as_secs_f64()
    );
    let gib = (stages * mb) as f64 / 1024.0;
    std::fs::remove_file(ws.join("artifacts/hash-cache.json")).expect("hash cache");
    let warm_pages = time("status");
    println!(
        "status, empty hash cache, files in page cache (rehash all): {:.2} s ({:.2} GiB/s)",
        warm_pages.as_secs_f64(),
        gib / warm_pages.as_secs_f64()
    );
    std::fs::remove_file(ws.join("artifacts/hash-cache.json")).expect("hash cache");
    drop_page_cache(&ws.join("artifacts/objects"));
    let cold = time("status");
    println!(
        "status, empty hash cache, page cache dropped (read + rehash all): {:.2} s ({:.2} GiB/s)",
        cold.as_secs_f64(),
        gib / cold.as_secs_f64()
    );
    let runs: Vec<Duration> = (0..repeat).map(|_| time("run")).collect();
    let statuses: Vec<Duration> = (0..repeat).map(|_| time("status")).collect();
    println!(
        "pipeline run, all cached: median {:.1} ms over {repeat}",
        median(runs).as_secs_f64() * 1e3
    );
    println!(
        "pipeline status, hash cache warm: median {:.1} ms over {repeat}",
        median(statuses).as_secs_f64() * 1e3
    );
}
