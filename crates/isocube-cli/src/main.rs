//! The `isocube` command. All logic lives in the library part of this crate ([`isocube_cli`]).

// Extraction builds its mesh in per-slab pieces on several threads; mimalloc keeps those
// allocations from being returned to the system and faulted in again on every run.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() -> std::process::ExitCode {
    isocube_cli::run(std::env::args_os())
}
