//! The `isocube` command. All logic lives in the library part of this crate ([`isocube_cli`]).

fn main() -> std::process::ExitCode {
    isocube_cli::run(std::env::args_os())
}
