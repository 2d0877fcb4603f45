#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| isocube_fuzz::run("chunk_join", data));
