//! Helpers shared by the command's integration tests.

/// A version 1.0 `.npy` file: `descr` (like `<f4`), `shape` as Python writes it (like
/// `(2, 2, 2)`), C order, then `data` as given (the header is padded so the data start on a
/// 64-byte boundary).
pub fn npy(descr: &str, shape: &str, data: &[u8]) -> Vec<u8> {
    let mut header =
        format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}").into_bytes();
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(b' ');
    }
    header.push(b'\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(&header);
    out.extend_from_slice(data);
    out
}
