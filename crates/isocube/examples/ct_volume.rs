//! Writes a CT-like 16-bit volume of any size as `.npy` (`a[z, y, x]`, read with `--axes zyx`),
//! one plane at a time, so volumes larger than memory can be made: a torso-like ellipsoid of
//! soft tissue (about 40 HU), a spine and ribs of bone (about 700 HU) and noise (σ ≈ 20 HU), air
//! outside (−1000 HU), stored as HU + 1024. Bone is at level 1324. The same body as
//! `bench/peers/volumes.py`'s CT volume, with noise from a hash of the point (so any plane can
//! be made on its own).
//!
//! `cargo run --release -p isocube --example ct_volume -- OUT.npy N`

use std::io::{BufWriter, Write};

fn main() {
    let mut args = std::env::args().skip(1);
    let (Some(out), Some(n)) = (args.next(), args.next()) else {
        eprintln!("usage: ct_volume OUT.npy N");
        std::process::exit(2);
    };
    let n: usize = match n.parse() {
        Ok(n) if n >= 2 => n,
        _ => {
            eprintln!("N must be a whole number of at least 2");
            std::process::exit(2);
        }
    };
    if let Err(e) = write(&out, n) {
        eprintln!("{out}: {e}");
        std::process::exit(1);
    }
}

fn write(out: &str, n: usize) -> std::io::Result<()> {
    let mut w = BufWriter::with_capacity(1 << 22, std::fs::File::create(out)?);
    let dict = format!("{{'descr': '<u2', 'fortran_order': False, 'shape': ({n}, {n}, {n}), }}");
    let mut header = dict.into_bytes();
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(b' ');
    }
    header.push(b'\n');
    w.write_all(b"\x93NUMPY\x01\x00")?;
    w.write_all(&(header.len() as u16).to_le_bytes())?;
    w.write_all(&header)?;
    let coord = |i: usize| -1.0 + 2.0 * i as f64 / (n - 1) as f64;
    let mut plane = vec![0u8; 2 * n * n];
    for k in 0..n {
        let z = coord(k);
        for j in 0..n {
            let y = coord(j);
            for i in 0..n {
                let x = coord(i);
                let body = (x / 0.9).powi(2) + (y / 0.6).powi(2) < 1.0;
                let mut hu = if body { 40.0 } else { -1000.0 };
                let spine = x * x + (y + 0.35).powi(2) < 0.01;
                let ring = (((x / 0.8).powi(2) + (y / 0.52).powi(2)).sqrt() - 1.0).abs() < 0.04;
                let rib = ring && (-4..=4).any(|r| (z - 0.18 * f64::from(r)).abs() < 0.03);
                if body && (spine || rib) {
                    hu = 700.0;
                }
                hu += 20.0 * noise((k * n + j) * n + i);
                let v = (hu + 1024.0).round().clamp(0.0, 65535.0) as u16;
                let at = 2 * (j * n + i);
                plane[at..at + 2].copy_from_slice(&v.to_le_bytes());
            }
        }
        w.write_all(&plane)?;
    }
    w.flush()
}

/// A standard-normal-like value from a hash of the point index (sum of four uniforms, scaled).
fn noise(index: usize) -> f64 {
    let mut h = (index as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0xD1B5_4A32_D192_ED03;
    let mut sum = 0.0;
    for _ in 0..4 {
        h ^= h >> 31;
        h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
        h ^= h >> 27;
        sum += (h >> 11) as f64 / (1u64 << 53) as f64;
    }
    (sum - 2.0) * 3.0f64.sqrt()
}
