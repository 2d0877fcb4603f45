#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| isocube_fuzz::run("dicom_jpeg12", data));
