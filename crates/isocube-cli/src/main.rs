//! The `isocube` command. All logic lives in the library part of this crate ([`isocube_cli`]).

// Extraction builds its mesh in per-slab pieces on several threads; mimalloc keeps those
// allocations from being returned to the system and faulted in again on every run.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() -> std::process::ExitCode {
    // Transparent huge pages make every first touch of the allocator's memory fault in 2 MiB,
    // and the partly used ones stay resident: on a 256³ extraction that was 45 MiB more peak
    // memory for no measurable speed (see README, Memory).
    #[cfg(target_os = "linux")]
    // SAFETY: PR_SET_THP_DISABLE only sets a flag of this process; no pointer is passed.
    unsafe {
        libc::prctl(libc::PR_SET_THP_DISABLE, 1, 0, 0, 0);
    }
    isocube_cli::run(std::env::args_os())
}
