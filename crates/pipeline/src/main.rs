//! `pipeline`: see the `pipeline` library and crates/pipeline/README.md.

fn main() -> std::process::ExitCode {
    pipeline::cli::main()
}
