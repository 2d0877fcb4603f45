//! What each fuzz target does with its input, shared with the replay test
//! (`crates/isocube/tests/fuzz_corpus.rs`), which feeds every checked-in corpus file through the
//! same function.
//!
//! A target names a reader. The input is written to a file with that reader's extension and
//! read through the public entry point, exactly as `isocube` would read a user's file. A reader
//! may refuse the input with an error; it must never panic, never allocate beyond the memory
//! limit, and whatever it accepts must satisfy the invariants checked below.

use std::path::{Path, PathBuf};

use isocube_io::{self as io, VolumeOptions};

/// Every fuzz target: its name (the file under `fuzz_targets/` and the corpus folder) and the
/// extension its input is given. `dicom` is a folder holding the input as its one slice; the
/// `dicom_*` targets fuzz one pixel data decoder each: the input is a small image's size and
/// a compressed frame, wrapped into a two-frame DICOM file by [`encapsulated_dicom`].
pub const TARGETS: &[(&str, &str)] = &[
    ("npy", "npy"),
    ("nrrd", "nrrd"),
    ("metaimage", "mha"),
    ("vti", "vti"),
    ("nifti", "nii"),
    ("nifti_gz", "nii.gz"),
    ("minc", "mnc"),
    ("tiff", "tif"),
    ("dicom", "dcm"),
    ("dicom_rle", "dcm"),
    ("dicom_jpeg", "dcm"),
    ("dicom_jpeg12", "dcm"),
    ("dicom_jpegls", "dcm"),
    ("dicom_j2k", "dcm"),
    ("rtstruct", "dcm"),
    ("ply", "ply"),
    ("obj", "obj"),
    ("stl", "stl"),
    ("off", "off"),
    ("poly_obj", "obj"),
    ("contours_csv", "csv"),
    ("contours_json", "json"),
    ("contours_dxf", "dxf"),
    ("tet_msh", "msh"),
    ("tet_mesh", "mesh"),
    ("tet_inp", "inp"),
    ("tet_vtu", "vtu"),
    ("chunk_mesh", "chunk"),
    ("chunk_join", "join"),
];

/// The memory a volume reader may use on a fuzz input: far below libFuzzer's `-malloc_limit_mb`,
/// so a reader that allocates before checking shows up as a crash.
pub const MAX_MEMORY: u64 = 64 << 20;

/// Runs target `name` on `data`, using `dir` for the input file.
///
/// # Panics
/// When a reader panics or accepts something that breaks an invariant: that is the bug the
/// fuzzer looks for.
pub fn run_in(dir: &Path, name: &str, data: &[u8]) {
    let &(_, ext) = TARGETS
        .iter()
        .find(|(n, _)| *n == name)
        .unwrap_or_else(|| panic!("no fuzz target {name}"));
    let path = if name == "dicom" {
        let series = dir.join("series");
        std::fs::create_dir_all(&series).unwrap();
        series.join("slice.dcm")
    } else {
        dir.join(format!("input.{ext}"))
    };
    let wrapped;
    let data = match name.strip_prefix("dicom_") {
        Some(codec) => {
            wrapped = encapsulated_dicom(codec, data);
            &wrapped[..]
        }
        None => data,
    };
    std::fs::write(&path, data).unwrap();
    let read = if name == "dicom" {
        path.parent().unwrap()
    } else {
        &path
    };
    match name {
        // A chunk mesh as a Dask task sends it: decoded, or refused; once decoded, what the
        // merges do with it must not panic, and its bytes come back as they were.
        "chunk_mesh" => {
            if let Ok(chunk) = isocube::extract::ChunkMesh::from_bytes(data) {
                assert_eq!(chunk.to_bytes(), data);
                let dims = chunk.cells.max.map(|m| m.saturating_add(1).min(1 << 20));
                let _ = isocube::extract::merge_chunks(dims, vec![chunk]);
            }
        }
        "chunk_join" => join_parts(data),
        // An RT Structure Set: read, or refused; what is read is finite and ordered.
        "rtstruct" => {
            let rois = io::read_rt_structure_set(read);
            same_outcome(&rois, &io::read_rt_structure_set_bytes(data, read));
            for roi in rois.iter().flatten() {
                for section in roi.stack.iter().flat_map(|s| s.sections()) {
                    assert!(section.z().is_finite());
                    for c in section.contours() {
                        assert!(c.points().len() >= 3);
                        assert!(c.points().iter().flatten().all(|v| v.is_finite()));
                    }
                }
            }
        }
        "ply" | "obj" | "stl" | "off" => {
            let mesh = io::read_mesh(read);
            same_outcome(&mesh, &io::read_mesh_bytes(data, read));
            if let Ok(mesh) = mesh {
                check_mesh(&mesh);
            }
        }
        "poly_obj" => {
            let poly = io::read_poly_mesh(read);
            same_outcome(&poly, &io::read_poly_mesh_bytes(data, read));
            if let Ok(poly) = poly {
                check_poly(&poly);
            }
        }
        n if n.starts_with("tet_") => {
            let mesh = io::read_tet_mesh(read);
            same_outcome(&mesh, &io::read_tet_mesh_bytes(data, read));
            if let Ok(mesh) = mesh {
                let n = mesh.positions.len();
                assert!(mesh.positions.iter().flatten().all(|c| c.is_finite()));
                assert!(mesh.tets.iter().flatten().all(|&i| (i as usize) < n));
                // What `isocube quality` does next with a mesh it has read.
                let _ = mesh.quality_report();
                let _ = mesh.check();
            }
        }
        n if n.starts_with("contours") => {
            let stack = io::read_contours(read);
            same_outcome(&stack, &io::read_contours_bytes(data, read));
            if let Ok(stack) = stack {
                for section in stack.sections() {
                    assert!(section.z().is_finite());
                    for c in section.contours() {
                        assert!(c.points().len() >= 3);
                        assert!(c.points().iter().flatten().all(|v| v.is_finite()));
                    }
                }
            }
        }
        _ => {
            let mut options = VolumeOptions::default();
            options.max_memory = Some(MAX_MEMORY);
            let from_file = io::read_volume_oriented(read, &options);
            // The same bytes from memory: the same volume, or an error too.
            if name != "dicom" {
                let from_bytes = io::read_volume_bytes(data, read, &options);
                match (&from_file, &from_bytes) {
                    (Ok((a, o)), Ok((b, p))) => {
                        // Bit for bit: NaN values compare too.
                        let bits = |g: &isocube::field::Grid| {
                            g.values().iter().map(|v| v.to_bits()).collect::<Vec<_>>()
                        };
                        assert_eq!(
                            (a.dims(), a.spacing(), a.origin(), o),
                            (b.dims(), b.spacing(), b.origin(), p)
                        );
                        assert_eq!(bits(a), bits(b));
                    }
                    (Err(_), Err(_)) => {}
                    _ => panic!("file and bytes disagree: {from_file:?} / {from_bytes:?}"),
                }
            }
            if let Ok((grid, orientation)) = from_file {
                let [nx, ny, nz] = grid.dims();
                assert_eq!(grid.values().len(), nx * ny * nz);
                assert!(grid.values().len() as u64 * 4 <= MAX_MEMORY);
                assert!(grid.spacing().iter().all(|s| s.is_finite() && *s > 0.0));
                assert!(grid.origin().iter().all(|o| o.is_finite()));
                let far = grid.dims().map(|d| (d - 1) as f64);
                let corner = orientation.world(&grid, far);
                assert!(corner.iter().all(|c| c.is_finite()));
                assert!(orientation.determinant().abs() > 0.0);
            }
        }
    }
}

/// A DICOM file of two frames, both `data[3..]` as one fragment, in the transfer syntax of
/// `codec` (`rle`, `jpeg` lossless, `jpeg12` extended, `jpegls`, `j2k`), of `1 + data[0] % 32` rows and
/// `1 + data[1] % 32` columns, 8, 16 or 32 bits as `data[2] % 3` says, signed when
/// `data[2] >= 128`.
pub fn encapsulated_dicom(codec: &str, data: &[u8]) -> Vec<u8> {
    let syntax: &[u8] = match codec {
        "rle" => b"1.2.840.10008.1.2.5\0",
        "jpeg" => b"1.2.840.10008.1.2.4.70",
        "jpeg12" => b"1.2.840.10008.1.2.4.51",
        "jpegls" => b"1.2.840.10008.1.2.4.80",
        _ => b"1.2.840.10008.1.2.4.90",
    };
    let &[rows, cols, kind, ..] = data else {
        return Vec::new();
    };
    let mut file = vec![0u8; 128];
    file.extend(b"DICM");
    let short = |out: &mut Vec<u8>, tag: (u16, u16), vr: &[u8], value: &[u8]| {
        out.extend(tag.0.to_le_bytes());
        out.extend(tag.1.to_le_bytes());
        out.extend(vr);
        out.extend((value.len() as u16).to_le_bytes());
        out.extend(value);
    };
    let mut meta = Vec::new();
    short(&mut meta, (2, 0x10), b"UI", syntax);
    short(&mut file, (2, 0), b"UL", &(meta.len() as u32).to_le_bytes());
    file.extend(meta);
    let us = |v: u16| v.to_le_bytes();
    short(&mut file, (0x28, 0x02), b"US", &us(1));
    short(&mut file, (0x28, 0x08), b"IS", b"2 ");
    short(
        &mut file,
        (0x28, 0x10),
        b"US",
        &us(1 + u16::from(rows % 32)),
    );
    short(
        &mut file,
        (0x28, 0x11),
        b"US",
        &us(1 + u16::from(cols % 32)),
    );
    let bits = [8u16, 16, 32][usize::from(kind % 3)];
    short(&mut file, (0x28, 0x100), b"US", &us(bits));
    short(&mut file, (0x28, 0x101), b"US", &us(bits));
    short(&mut file, (0x28, 0x103), b"US", &us(u16::from(kind >> 7)));
    // Pixel Data, undefined length: an empty basic offset table, the fragment twice.
    file.extend([
        0xE0, 0x7F, 0x10, 0x00, b'O', b'B', 0, 0, 0xFF, 0xFF, 0xFF, 0xFF,
    ]);
    let mut fragment = data[3..].to_vec();
    if fragment.len() % 2 == 1 {
        fragment.push(0);
    }
    let item = |out: &mut Vec<u8>, value: &[u8]| {
        out.extend([0xFE, 0xFF, 0x00, 0xE0]);
        out.extend((value.len() as u32).to_le_bytes());
        out.extend(value);
    };
    item(&mut file, &[]);
    item(&mut file, &fragment);
    item(&mut file, &fragment);
    file.extend([0xFE, 0xFF, 0xDD, 0xE0, 0, 0, 0, 0]);
    file
}

/// [`run_in`] with a folder of this process's own under the system's temporary directory
/// (`/dev/shm` where there is one, so the fuzzer does not wear a disk).
pub fn run(name: &str, data: &[u8]) {
    thread_local! {
        static DIR: PathBuf = {
            let base = Path::new("/dev/shm");
            let base = if base.is_dir() { base.to_path_buf() } else { std::env::temp_dir() };
            let dir = base.join(format!("isocube-fuzz-{}", std::process::id()));
            std::fs::create_dir_all(&dir).unwrap();
            dir
        };
    }
    DIR.with(|dir| run_in(dir, name, data));
}

fn check_mesh(mesh: &isocube::mesh::Mesh) {
    let n = mesh.positions.len();
    assert!(mesh.positions.iter().flatten().all(|c| c.is_finite()));
    assert!(mesh.triangles.iter().flatten().all(|&i| (i as usize) < n));
    assert!(mesh.normals.is_empty() || mesh.normals.len() == n);
    // What every command does next with a mesh it has read.
    let _ = mesh.report();
}

fn check_poly(poly: &isocube::subdiv::PolyMesh) {
    assert!(poly.positions.iter().flatten().all(|c| c.is_finite()));
    if poly.validate().is_err() || poly.faces.len() > 2_000 {
        return;
    }
    // A cage that validates must subdivide: one level, and the result is finite.
    let options = isocube::subdiv::SubdivOptions::default();
    if let Ok(fine) = isocube::subdiv::subdivide(poly, 1, &options) {
        assert!(fine.positions.iter().flatten().all(|c| c.is_finite()));
    }
}

/// A file and the same bytes from memory: the same value, or an error both ways.
fn same_outcome<T: PartialEq + std::fmt::Debug>(
    file: &Result<T, io::IoError>,
    bytes: &Result<T, io::IoError>,
) {
    match (file, bytes) {
        (Ok(a), Ok(b)) => assert_eq!(a, b),
        (Err(_), Err(_)) => {}
        _ => panic!("file and bytes disagree: {file:?} / {bytes:?}"),
    }
}

/// The bytes a cluster's join passes around (outlines, places, placed pieces), each from its
/// own decoder: whatever decodes round-trips, and using it never panics.
fn join_parts(data: &[u8]) {
    use isocube::extract::{
        assemble, CellBox, ChunkOutline, ChunkPlace, ExtractOptions, Extractor, JoinLayout,
        PlacedPiece,
    };
    if let Ok(outline) = ChunkOutline::from_bytes(data) {
        assert_eq!(outline.to_bytes(), data);
        let cells = outline.cells();
        let dims = cells.max.map(|m| m.saturating_add(1).min(1 << 20));
        if let Ok(layout) = JoinLayout::new(dims, std::slice::from_ref(&outline)) {
            assert_eq!(layout.places().len(), 1);
        }
    }
    if let Ok(place) = ChunkPlace::from_bytes(data) {
        assert_eq!(place.to_bytes(), data);
        // Placed against a real chunk of the box it names, when that box is small.
        let cells = place.cells();
        let small = (0..3).all(|a| cells.min[a] < cells.max[a] && cells.max[a] <= 12);
        if small {
            let dims = cells.max.map(|m| m + 1);
            let grid = isocube::field::Sample::Tangle.grid(dims[0].max(dims[1]).max(dims[2]));
            if let Ok(chunk) = Extractor::new(&grid, &ExtractOptions::default())
                .and_then(|e| e.mesh_box(CellBox::new(cells.min, cells.max)))
            {
                if let Ok(pieces) = place.place(&chunk) {
                    let [v, t] = place.whole();
                    assert!(pieces
                        .iter()
                        .all(|p| p.first_vertex + p.positions.len() as u64 <= v
                            && p.first_triangle + p.triangles.len() as u64 <= t));
                }
            }
        }
    }
    if let Ok(pieces) = PlacedPiece::list_from_bytes(data) {
        assert_eq!(PlacedPiece::list_to_bytes(&pieces), data);
        let v: u64 = pieces.iter().map(|p| p.positions.len() as u64).sum();
        let t: u64 = pieces.iter().map(|p| p.triangles.len() as u64).sum();
        let normals = pieces.first().is_some_and(|p| !p.normals.is_empty());
        if let Ok(mesh) = assemble(v as usize, t as usize, normals, pieces) {
            assert_eq!(mesh.positions.len() as u64, v);
        }
    }
}
