//! Replays the fuzzers' checked-in inputs (`fuzz/corpus/TARGET/` and `fuzz/regressions/TARGET/`)
//! through the same harness the fuzz targets run, so every input that once crashed a reader, and
//! every input that reaches new code, is checked by the normal test suite without a fuzzer.

// `run` (a per-process folder) is for the fuzzer; the test gives its own folder to `run_in`.
#[allow(dead_code)]
#[path = "../../../fuzz/harness.rs"]
mod harness;

use std::path::Path;

#[test]
fn every_fuzz_input_is_read_or_refused_cleanly() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz");
    let scratch = tempfile::tempdir().unwrap();
    let mut replayed = 0;
    for &(target, _) in harness::TARGETS {
        let mut inputs = 0;
        for kind in ["corpus", "regressions"] {
            let Ok(entries) = std::fs::read_dir(root.join(kind).join(target)) else {
                continue;
            };
            let mut files: Vec<_> = entries.map(|e| e.unwrap().path()).collect();
            files.sort();
            for file in files {
                // A fuzzer running beside the test may just have replaced the file.
                let data = match std::fs::read(&file) {
                    Err(e) if e.kind() == std::io::ErrorKind::NotFound => continue,
                    read => read.unwrap(),
                };
                let outcome = std::panic::catch_unwind(|| {
                    harness::run_in(scratch.path(), target, &data);
                });
                assert!(outcome.is_ok(), "{target}: {} panicked", file.display());
                inputs += 1;
            }
        }
        // Every target has at least its seeds, or the fuzzer would start from nothing.
        assert!(inputs > 0, "no corpus for fuzz target {target}");
        replayed += inputs;
    }
    eprintln!("{replayed} fuzz inputs replayed");
}

/// The seeds of the pixel data decoders' targets are frames cut from the DICOM fixtures: each
/// decodes, so the fuzzers start inside the decoders rather than at their first check.
#[test]
fn decoder_seeds_decode() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/corpus");
    let options = isocube_io::VolumeOptions::default();
    for codec in ["rle", "jpeg", "jpeg12", "jpegls", "j2k"] {
        let mut seeds = 0;
        for entry in std::fs::read_dir(root.join(format!("dicom_{codec}"))).unwrap() {
            let path = entry.unwrap().path();
            if !path
                .file_name()
                .unwrap()
                .to_str()
                .unwrap()
                .starts_with("seed-")
            {
                continue;
            }
            let file = harness::encapsulated_dicom(codec, &std::fs::read(&path).unwrap());
            let read = isocube_io::read_volume_bytes(&file, Path::new("seed.dcm"), &options);
            let (grid, _) = read.unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            assert_eq!(grid.dims(), [12, 10, 2]);
            // The two frames are the same fragment.
            let (a, b) = grid.values().split_at(120);
            assert_eq!(a, b);
            seeds += 1;
        }
        assert!(seeds > 0, "{codec}");
    }
}
