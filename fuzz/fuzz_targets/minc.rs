#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| isocube_fuzz::run("minc", data));
