//! A tiny stage for the orchestrator's tests: follows the stage protocol and writes one file
//! whose bytes derive only from its context (stage name, shard, parameters, input files), so
//! runs are deterministic and byte-comparable.
//!
//! Parameters (all optional; any other key, such as a matrix key, is just carried along):
//! `file` (output name, default `out.txt`), `fail` (print to stderr and exit 3), `steps`
//! (progress steps), `summary` (the `::summary` text), `gated` / `gated_shards` (while the
//! file named by env `TEST_STAGE_GATE` exists, wait: lets a test hold a stage mid-run),
//! `fail_first_attempts` (count attempts in the unit's scratch directory and fail until this
//! many have failed; the output then records how many earlier attempts the scratch kept),
//! `hold_at` (report that many of `steps` done, with the message `held here`, then wait while
//! the gate file exists: a unit held mid-run with known progress).
//! If env `TEST_STAGE_LOG` names a file, `start UNIT` and `end UNIT` lines are appended to it,
//! so tests can count which units really ran.

use std::io::Write;
use std::path::Path;

fn log(line: &str) {
    if let Some(p) = std::env::var_os("TEST_STAGE_LOG") {
        let mut f = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(p)
            .expect("log file");
        f.write_all(format!("{line}\n").as_bytes())
            .expect("log write");
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let ctx = stage_kit::StageContext::load()?;
    let params = ctx.raw_params().clone();
    let get = |k: &str| params.get(k);
    let unit = if ctx.shard.count > 1 {
        format!("{}#{}", ctx.stage, ctx.shard.index)
    } else {
        ctx.stage.clone()
    };
    log(&format!("start {unit}"));
    log(&format!("pid {unit} {}", std::process::id()));

    let gated = get("gated").and_then(|v| v.as_bool()).unwrap_or(false)
        || get("gated_shards")
            .and_then(|v| v.as_array())
            .is_some_and(|a| a.iter().any(|x| x.as_u64() == Some(ctx.shard.index as u64)));
    if gated {
        if let Some(gate) = std::env::var_os("TEST_STAGE_GATE") {
            while Path::new(&gate).exists() {
                std::thread::sleep(std::time::Duration::from_millis(20));
            }
        }
    }
    let mut earlier_attempts = None;
    if let Some(n) = get("fail_first_attempts").and_then(|v| v.as_u64()) {
        let scratch = ctx
            .scratch
            .as_ref()
            .ok_or("no scratch directory in the context")?;
        let counter = scratch.join("attempts");
        let before: u64 = std::fs::read_to_string(&counter)
            .ok()
            .and_then(|s| s.trim().parse().ok())
            .unwrap_or(0);
        std::fs::write(&counter, format!("{}", before + 1))?;
        if before < n {
            eprintln!("boom: attempt {} of {unit} fails on purpose", before + 1);
            return Err("deliberate failure".into());
        }
        earlier_attempts = Some(before);
    }
    if get("fail").and_then(|v| v.as_bool()).unwrap_or(false) {
        eprintln!("early noise that the tail may drop");
        eprintln!("boom: deliberate failure in {unit}");
        return Err("deliberate failure".into());
    }

    let steps = get("steps").and_then(|v| v.as_u64()).unwrap_or(3);
    let progress = ctx.progress(steps);
    let mut text = format!(
        "stage {}\nshard {}/{}\nparams {}\n",
        ctx.stage,
        ctx.shard.index,
        ctx.shard.count,
        serde_json::to_string(&params)?
    );
    let names: Vec<String> = ctx.input_names().map(str::to_owned).collect();
    for name in names {
        for (k, dir) in ctx.input_dirs(&name)?.iter().enumerate() {
            let mut files: Vec<_> = std::fs::read_dir(dir)?.collect::<Result<Vec<_>, _>>()?;
            files.sort_by_key(|e| e.file_name());
            for f in files {
                let body = std::fs::read_to_string(f.path())?;
                text.push_str(&format!(
                    "input {name}[{k}] {}:\n",
                    f.file_name().to_string_lossy()
                ));
                for l in body.lines() {
                    text.push_str(&format!("  {l}\n"));
                }
            }
        }
    }
    if let Some(k) = earlier_attempts {
        text.push_str(&format!("earlier attempts {k}\n"));
    }
    let mut done = 0;
    if let Some(k) = get("hold_at").and_then(|v| v.as_u64()) {
        // Printed directly: `Progress` rate-limits lines, and this one must not be dropped.
        let k = k.min(steps);
        println!("{} {k} {steps} held here", stage_kit::PROGRESS_PREFIX);
        std::io::stdout().flush()?;
        log(&format!("held {unit}"));
        if let Some(gate) = std::env::var_os("TEST_STAGE_GATE") {
            while Path::new(&gate).exists() {
                std::thread::sleep(std::time::Duration::from_millis(20));
            }
        }
        done = k;
        progress.inc(k);
    }
    for _ in done..steps {
        progress.inc(1);
    }
    let file = get("file")
        .and_then(|v| v.as_str())
        .unwrap_or("out.txt")
        .to_owned();
    std::fs::write(ctx.output_path(&file), text)?;
    if let Some(s) = get("summary").and_then(|v| v.as_str()) {
        stage_kit::summary(s);
    }
    log(&format!("end {unit}"));
    Ok(())
}
