//! Readers and writers on their own: volumes read from files in the forms users hand the
//! command (`.npy` in both axis orders, mapped; `.nii.gz`; zlib MetaImage), and a mesh written
//! in the formats that carry the most bytes (binary PLY, OBJ, GLB, MSH).
//!
//! `cargo bench -p isocube-io --features nifti --bench io` (add `-- --quick` for a short run).
//! Readers report bytes of values per second, writers bytes written per second. The files are
//! made in a temporary folder from the tangle sample (128³ points, `f32`).

use std::io::Write;
use std::path::Path;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use isocube::extract::{extract, ExtractOptions};
use isocube::field::Sample;
use isocube_io::{
    read_volume, write_mesh_to, MappedVolume, MeshFormat, MeshWriteOptions, NpyAxes, VolumeOptions,
};

const N: usize = 128;

/// The sample's values, x fastest.
fn values() -> Vec<f32> {
    Sample::Tangle.grid(N).values().to_vec()
}

fn npy(path: &Path, values: &[f32], transposed: bool) {
    let dict = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': ({N}, {N}, {N}), }}");
    let mut header = format!("{dict:<117}");
    header.truncate(117);
    header.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    // C order: a[z, y, x] is the grid's own order; a[x, y, z] is its transpose.
    for index in 0..N * N * N {
        let (a, b, c) = (index / (N * N), index / N % N, index % N);
        let v = if transposed {
            values[a + b * N + c * N * N]
        } else {
            values[index]
        };
        out.extend_from_slice(&v.to_le_bytes());
    }
    std::fs::write(path, out).unwrap();
}

fn nifti_gz(path: &Path, values: &[f32]) {
    let mut h = vec![0u8; 352];
    h[0..4].copy_from_slice(&348i32.to_le_bytes());
    for (i, d) in [3i16, N as i16, N as i16, N as i16, 1, 1, 1, 1]
        .iter()
        .enumerate()
    {
        h[40 + 2 * i..42 + 2 * i].copy_from_slice(&d.to_le_bytes());
    }
    h[70..72].copy_from_slice(&16i16.to_le_bytes());
    h[72..74].copy_from_slice(&32i16.to_le_bytes());
    for (i, p) in [1.0f32, 1.0, 1.0, 1.0].iter().enumerate() {
        h[76 + 4 * i..80 + 4 * i].copy_from_slice(&p.to_le_bytes());
    }
    h[108..112].copy_from_slice(&352.0f32.to_le_bytes());
    h[344..348].copy_from_slice(b"n+1\0");
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    gz.write_all(&h).unwrap();
    gz.write_all(bytemuck::cast_slice(values)).unwrap();
    std::fs::write(path, gz.finish().unwrap()).unwrap();
}

fn metaimage_zlib(path: &Path, values: &[f32]) {
    let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
    z.write_all(bytemuck::cast_slice(values)).unwrap();
    let data = z.finish().unwrap();
    let mut out = format!(
        "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n\
         CompressedData = True\nCompressedDataSize = {}\nDimSize = {N} {N} {N}\n\
         ElementType = MET_FLOAT\nElementDataFile = LOCAL\n",
        data.len()
    )
    .into_bytes();
    out.extend_from_slice(&data);
    std::fs::write(path, out).unwrap();
}

fn readers(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let v = values();
    let files = [
        ("npy-zyx", "zyx.npy", NpyAxes::Zyx),
        ("npy-xyz", "xyz.npy", NpyAxes::Xyz),
        ("nii.gz", "v.nii.gz", NpyAxes::Xyz),
        ("mha-zlib", "v.mha", NpyAxes::Xyz),
    ];
    npy(&dir.path().join("zyx.npy"), &v, false);
    npy(&dir.path().join("xyz.npy"), &v, true);
    nifti_gz(&dir.path().join("v.nii.gz"), &v);
    metaimage_zlib(&dir.path().join("v.mha"), &v);
    let mut group = c.benchmark_group("read");
    group.sample_size(10);
    group.throughput(Throughput::Bytes((4 * v.len()) as u64));
    for (name, file, axes) in files {
        let path = dir.path().join(file);
        let mut options = VolumeOptions::default();
        options.npy_axes = axes;
        // Every reader must give the sample's values, in the grid's order.
        assert_eq!(
            read_volume(&path, &options).unwrap().values(),
            &v[..],
            "{name}"
        );
        group.bench_function(BenchmarkId::new("read_volume", name), |b| {
            b.iter(|| read_volume(&path, &options).unwrap())
        });
        if file.ends_with(".npy") {
            // What `extract` does with a mapped file: open it and take the view, no copy.
            group.bench_function(BenchmarkId::new("mapped", name), |b| {
                b.iter(|| {
                    let volume = MappedVolume::open(&path, &options).unwrap();
                    assert!(volume.view().is_some());
                    volume
                })
            });
        }
    }
    group.finish();
}

fn writers(c: &mut Criterion) {
    let (mesh, _) = extract(&Sample::Tangle.grid(2 * N), &ExtractOptions::default()).unwrap();
    let options = MeshWriteOptions::default();
    let mut group = c.benchmark_group("write");
    group.sample_size(10);
    for format in [
        MeshFormat::Ply,
        MeshFormat::Obj,
        MeshFormat::Glb,
        MeshFormat::Msh,
    ] {
        let mut out = Vec::new();
        write_mesh_to(&mut out, format, &mesh, &options).unwrap();
        group.throughput(Throughput::Bytes(out.len() as u64));
        group.bench_function(
            BenchmarkId::new("write_mesh_to", format!("{format:?}")),
            |b| {
                b.iter(|| {
                    out.clear();
                    write_mesh_to(&mut out, format, &mesh, &options).unwrap();
                })
            },
        );
    }
    group.finish();
}

criterion_group!(benches, readers, writers);
criterion_main!(benches);
