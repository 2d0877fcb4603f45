//! Malformed inputs of every format the command reads: each one exits with code 2, an error
//! that names the file and says what is wrong, no panic, and no output file.

use std::process::Command;

mod common;
use common::npy;

/// A NIfTI-1 header (348 bytes + 4 bytes of extension flag) for `dims` of int16.
fn nifti(dims: &[u16], datatype: i16, magic: &[u8; 4]) -> Vec<u8> {
    let mut h = vec![0u8; 352];
    h[0..4].copy_from_slice(&348i32.to_le_bytes());
    let mut dim = [1u16; 8];
    dim[0] = dims.len() as u16;
    dim[1..=dims.len()].copy_from_slice(dims);
    for (i, d) in dim.iter().enumerate() {
        h[40 + 2 * i..42 + 2 * i].copy_from_slice(&d.to_le_bytes());
    }
    h[70..72].copy_from_slice(&datatype.to_le_bytes());
    h[72..74].copy_from_slice(&16i16.to_le_bytes());
    for i in 0..8 {
        h[76 + 4 * i..80 + 4 * i].copy_from_slice(&1f32.to_le_bytes());
    }
    h[108..112].copy_from_slice(&352f32.to_le_bytes());
    h[344..348].copy_from_slice(magic);
    h
}

fn zlib(data: &[u8]) -> Vec<u8> {
    use std::io::Write;
    let mut e = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
    e.write_all(data).unwrap();
    e.finish().unwrap()
}

fn gzip(data: &[u8]) -> Vec<u8> {
    use std::io::Write;
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
    e.write_all(data).unwrap();
    e.finish().unwrap()
}

fn tiff_page(width: u32, height: u32, samples: u16, data_len: u32) -> Vec<u8> {
    // A minimal little-endian baseline TIFF: one strip, 8-bit grey (or RGB).
    let entries: Vec<(u16, u16, u32, u32)> = vec![
        (256, 4, 1, width),
        (257, 4, 1, height),
        (258, 3, 1, 8),
        (259, 3, 1, 1),
        (262, 3, 1, if samples == 3 { 2 } else { 1 }),
        (273, 4, 1, 8 + 2 + 12 * 9 + 4),
        (277, 3, 1, u32::from(samples)),
        (278, 4, 1, height),
        (279, 4, 1, data_len),
    ];
    let mut out = b"II*\0".to_vec();
    out.extend_from_slice(&8u32.to_le_bytes());
    out.extend_from_slice(&(entries.len() as u16).to_le_bytes());
    for (tag, kind, count, value) in entries {
        out.extend_from_slice(&tag.to_le_bytes());
        out.extend_from_slice(&kind.to_le_bytes());
        out.extend_from_slice(&count.to_le_bytes());
        out.extend_from_slice(&value.to_le_bytes());
    }
    out.extend_from_slice(&0u32.to_le_bytes());
    out.resize(out.len() + data_len as usize, 7u8);
    out
}

const MHA: &str = "ObjectType = Image\nNDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\n";
const VTI_HEAD: &str =
    r#"<VTKFile type="ImageData" version="1.0" byte_order="LittleEndian" header_type="UInt32">"#;

/// (file name, content, extra command-line arguments, what the error must say)
fn cases() -> Vec<(&'static str, Vec<u8>, Vec<&'static str>, &'static str)> {
    let ply = |body: &str| body.as_bytes().to_vec();
    let vti = |image: &str, array: &str| {
        format!("{VTI_HEAD}<ImageData {image}><Piece Extent=\"0 1 0 1 0 1\"><PointData>{array}</PointData></Piece></ImageData></VTKFile>").into_bytes()
    };
    vec![
        // Raw volumes.
        ("short.raw", vec![0; 100], vec!["--dims", "4,4,4", "--type", "u16"], "need 128 bytes"),
        ("huge.raw", vec![0; 8], vec!["--dims", "4294967296,4294967296,65536", "--type", "u8"], "overflow"),
        ("half.raw", vec![0; 8], vec!["--dims", "2,2,2"], "need both --dims and --type"),
        ("nodims.dat", vec![0; 8], vec![], "unknown volume extension"),
        // NumPy.
        ("magic.npy", b"NUMPY\x01\x00".to_vec(), vec![], "NUMPY magic"),
        ("cut.npy", npy("<f4", "(2, 2, 2)", &[0; 32])[..20].to_vec(), vec![], "header runs past"),
        ("complex.npy", npy("<c8", "(2, 2, 2)", &[0; 64]), vec![], "dtype '<c8'"),
        ("flat.npy", npy("<f4", "(8,)", &[0; 32]), vec![], "3-D array"),
        ("short.npy", npy("<f4", "(2, 2, 2)", &[0; 31]), vec![], "the file has 31"),
        ("dict.npy", npy("<f4", "(2, 2, 2", &[0; 32]), vec![], "not a size"),
        ("bigshape.npy", npy("|u1", "(100000, 100000, 100000)", &[0; 8]), vec![], "needs 1000000000000000 data bytes"),
        // NRRD.
        ("nomagic.nrrd", b"NRD0004\ntype: uchar\n\n".to_vec(), vec![], "NRRD"),
        ("type.nrrd", b"NRRD0004\ntype: quaternion\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n".to_vec(), vec![], "type 'quaternion'"),
        ("nosizes.nrrd", b"NRRD0004\ntype: uchar\ndimension: 3\nencoding: raw\n\n\0\0\0\0\0\0\0\0".to_vec(), vec![], "sizes"),
        ("short.nrrd", b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n\0\0\0".to_vec(), vec![], "values need 8 bytes"),
        ("badgz.nrrd", b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: gzip\n\nnot gzip at all".to_vec(), vec![], "gzip"),
        ("detached.nhdr", b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\ndata file: gone.raw\n\n".to_vec(), vec![], "gone.raw"),
        ("fourd.nrrd", b"NRRD0004\ntype: uchar\ndimension: 4\nsizes: 2 2 2 2\nencoding: raw\n\n".to_vec(), vec![], "4 axes"),
        // NIfTI.
        ("cut.nii", nifti(&[2, 2, 2], 4, b"n+1\0")[..100].to_vec(), vec![], "ends inside its header"),
        ("magic.nii", nifti(&[2, 2, 2], 4, b"xyz\0").into_iter().chain([0u8; 16]).collect(), vec![], "Invalid NIfTI-1 file"),
        ("short.nii", nifti(&[2, 2, 2], 4, b"n+1\0").into_iter().chain([0u8; 7]).collect(), vec![], "need 16 bytes from byte 352, the file has 359"),
        ("frames.nii", nifti(&[2, 2, 2, 3], 4, b"n+1\0").into_iter().chain([0u8; 48]).collect(), vec![], "frames"),
        ("badgz.nii.gz", b"\x1f\x8b\x08\0this is not deflate".to_vec(), vec![], "corrupt gzip data"),
        ("bigdims.nii", nifti(&[30000, 30000, 30000], 4, b"n+1\0").into_iter().chain([0u8; 16]).collect(), vec![], "need 54000000000000 bytes from byte 352"),
        ("type.nii", nifti(&[2, 2, 2], 1999, b"n+1\0").into_iter().chain([0u8; 16]).collect(), vec![], "1999"),
        // MetaImage.
        ("nodims.mha", b"NDims = 3\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n".to_vec(), vec![], "DimSize"),
        ("rgb.mha", format!("{MHA}ElementNumberOfChannels = 3\nElementDataFile = LOCAL\n").into_bytes(), vec![], "channels"),
        ("short.mha", [format!("{MHA}ElementDataFile = LOCAL\n").into_bytes(), vec![1; 5]].concat(), vec![], "need 8 bytes"),
        ("badzlib.mha", [format!("{MHA}CompressedData = True\nElementDataFile = LOCAL\n").into_bytes(), b"garbage".to_vec()].concat(), vec![], "zlib"),
        ("gone.mhd", format!("{MHA}ElementDataFile = gone.raw\n").into_bytes(), vec![], "gone.raw"),
        ("ndims.mha", b"NDims = 5\n".to_vec(), vec![], "NDims 5"),
        ("type.mha", b"NDims = 3\nDimSize = 2 2 2\nElementType = MET_STRING\nElementDataFile = LOCAL\n".to_vec(), vec![], "MET_STRING"),
        ("zlibsize.mha", [format!("{MHA}CompressedData = True\nElementDataFile = LOCAL\n").into_bytes(), zlib(&[1; 5])].concat(), vec![], "zlib stream gives 5"),
        // VTK ImageData.
        ("poly.vti", br#"<VTKFile type="PolyData"><PolyData/></VTKFile>"#.to_vec(), vec![], "PolyData"),
        ("noextent.vti", vti("Origin=\"0 0 0\"", ""), vec![], "WholeExtent"),
        ("words.vti", vti("WholeExtent=\"0 1 0 1 0 1\"", r#"<DataArray type="Float32" Name="v" format="ascii">1 2 x 4 5 6 7 8</DataArray>"#), vec![], "not a list of numbers"),
        ("count.vti", vti("WholeExtent=\"0 1 0 1 0 1\"", r#"<DataArray type="Float32" Name="v" format="ascii">1 2 3</DataArray>"#), vec![], "3 values"),
        ("base64.vti", vti("WholeExtent=\"0 1 0 1 0 1\"", r#"<DataArray type="UInt8" Name="v" format="binary">@@@@####</DataArray>"#), vec![], "base64"),
        ("offset.vti", [vti("WholeExtent=\"0 1 0 1 0 1\"", r#"<DataArray type="UInt8" Name="v" format="appended" offset="999"/>"#), b"<AppendedData encoding=\"raw\">_\x08\0\0\0".to_vec()].concat(), vec![], "offset 999"),
        ("nodata.vti", vti("WholeExtent=\"0 1 0 1 0 1\"", ""), vec![], "no point data array"),
        ("lz4.vti", br#"<VTKFile type="ImageData" compressor="vtkLZ4DataCompressor"><ImageData WholeExtent="0 1 0 1 0 1"/></VTKFile>"#.to_vec(), vec![], "vtkLZ4DataCompressor"),
        ("xml.vti", b"<VTKFile type=\"ImageData\"><ImageData WholeExtent=\"0 1 0 1 0 1\"></Other></VTKFile>".to_vec(), vec![], "XML"),
        // TIFF.
        ("text.tif", b"this is not a tiff".to_vec(), vec![], "TIFF"),
        ("cut.tif", tiff_page(4, 4, 1, 16)[..60].to_vec(), vec![], "not a readable TIFF"),
        ("rgb.tif", tiff_page(2, 2, 3, 12), vec![], "3 samples per pixel: choose one with --channel"),
        ("strip.tif", tiff_page(4, 4, 1, 16)[..126].to_vec(), vec![], "page 0"),
        // Absurd sizes: refused before allocating, under the default limit (the machine's
        // memory) or a given one.
        // (Uncompressed files are mapped and hold nothing with `mc`: ternary extraction reads
        // the whole volume, as `f32` values converted from the map.)
        ("limit.npy", npy("<f8", "(64, 64, 64)", &[0; 1 << 21]), vec!["--max-memory", "512K", "--method", "ternary"], "reading it needs 1.0 MiB of memory, more than the limit of 512.0 KiB"),
        ("huge.mha", b"NDims = 3\nDimSize = 100000 100000 100000\nElementType = MET_UCHAR\nCompressedData = True\nElementDataFile = LOCAL\nxx".to_vec(), vec![], "header field 'DimSize': reading it needs 4.4 PiB"),
        ("huge.vti", format!("{VTI_HEAD}<ImageData WholeExtent=\"0 99999 0 99999 0 99999\"><Piece Extent=\"0 99999 0 99999 0 99999\"><PointData><DataArray type=\"UInt8\" Name=\"v\" format=\"binary\">AAAA</DataArray></PointData></Piece></ImageData></VTKFile>").into_bytes(), vec![], "header field 'WholeExtent': reading it needs 4.4 PiB"),
        ("huge.nii.gz", gzip(&nifti(&[30000, 30000, 30000], 4, b"n+1\0")), vec![], "header field 'dim': reading it needs 245.6 TiB"),
        ("zeros.nrrd", [b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 1000 1000 1000\nencoding: gzip\n\n".to_vec(), gzip(&[0; 1000])].concat(), vec!["--max-memory", "64M"], "header field 'sizes': reading it needs 4.7 GiB"),
        ("bomb.nrrd", [b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nbyte skip: -1\nencoding: gzip\n\n".to_vec(), gzip(&vec![0; 64 << 20])].concat(), vec!["--max-memory", "16M"], "header field 'byte skip': reading it needs 64.2 MiB of memory, more than the limit of 16.0 MiB"),
        ("page.tif", tiff_page(60000, 60000, 1, 16), vec!["--max-memory", "1G"], "'page 0': reading it needs 40.2 GiB"),
        ("limit.raw", vec![0; 4096], vec!["--dims", "16,16,16", "--type", "u8", "--max-memory", "12K", "--method", "ternary"], "needs 16.0 KiB of memory, more than the limit of 12.0 KiB"),
        ("size.npy", npy("<f4", "(2, 2, 2)", &[0; 32]), vec!["--max-memory", "lots"], "'lots' is not a size"),
        // Meshes (read by `info`).
        ("magic.ply", ply("plx\nformat ascii 1.0\nend_header\n"), vec![], "not a PLY file"),
        ("count.ply", ply("ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n0.000 0.000 0.000\n"), vec![], "data ends before"),
        ("index.ply", ply("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 9\n"), vec![], "outside 0..3"),
        ("nan.ply", ply("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n"), vec![], "not a finite number"),
        ("binary.ply", [b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n".to_vec(), vec![0; 20]].concat(), vec![], "3 items cannot fit in the 20 bytes"),
        ("zero.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n".to_vec(), vec![], "index 0"),
        ("word.obj", b"v 0 zero 0\n".to_vec(), vec![], "'zero' is not a number"),
        ("utf8.obj", b"v 0 0 0\n# \xff\xfe\n".to_vec(), vec![], "UTF-8"),
        ("short.stl", [vec![0u8; 80], 10u32.to_le_bytes().to_vec(), vec![0u8; 100]].concat(), vec![], "does not match the triangle count"),
        ("nan.stl", b"solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex nan 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid t\n".to_vec(), vec![], "line 5: coordinate NaN is not a finite number"),
        ("cut.stl", b"solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n".to_vec(), vec![], "line 5: the file ends before 'endsolid'"),
        ("inf.off", b"OFF\n3 1 0\n0 0 0\ninf 0 0\n0 1 0\n3 0 1 2\n".to_vec(), vec![], "line 4: coordinate inf is not a finite number"),
        ("lies.off", b"OFF\n3 5 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n".to_vec(), vec![], "all faces"),
        ("index.off", b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n".to_vec(), vec![], "outside 0..3"),
        ("written.glb", b"glTF".to_vec(), vec![], "reads only"),
        // Contours.
        ("bad.csv", b"section,z,contour,x,y\n0,0,0,1,one\n".to_vec(), vec![], "'one' is not a number"),
        ("bad.json", b"{\"sections\": [".to_vec(), vec![], "EOF while parsing"),
        ("nan.csv", b"section,z,contour,x,y\na,0,o,0,0\na,0,o,NaN,0\na,0,o,1,1\na,0,o,0,0\n".to_vec(), vec![], "finite"),
        ("utf8.csv", b"section,z,contour,x,y\na,0,o,0,\xff\n".to_vec(), vec![], "not UTF-8 text"),
        ("cross.csv", b"section,z,contour,x,y\na,0,p,0,0\na,0,p,2,0\na,0,p,2,2\na,0,p,0,0\na,0,q,1,-1\na,0,q,3,1\na,0,q,1,1\na,0,q,1,-1\n".to_vec(), vec![], "cross"),
        ("inf.json", b"{\"sections\": [{\"z\": 0, \"contours\": [[[0,0],[1e999,0],[1,1],[0,0]]]}]}".to_vec(), vec![], "inf.json"),
        ("samez.json", b"{\"sections\": [{\"z\": 1, \"contours\": [[[0,0],[1,0],[1,1],[0,0]]]}, {\"z\": 1, \"contours\": [[[0,0],[1,0],[1,1],[0,0]]]}]}".to_vec(), vec![], "header field 'sections[1].z': sections '0' and '1' are both at z = 1"),
        ("open.dxf", b"0\nSECTION\n2\nENTITIES\n0\nLWPOLYLINE\n5\nA1\n90\n3\n70\n0\n38\n0\n10\n0\n20\n0\n10\n1\n20\n0\n10\n1\n20\n1\n0\nENDSEC\n0\nEOF\n".to_vec(), vec![], "is open"),
        ("empty.dxf", b"0\nSECTION\n2\nENTITIES\n0\nENDSEC\n0\nEOF\n".to_vec(), vec![], "no LWPOLYLINE or POLYLINE entity"),
        // Subdivision cages.
        ("cage-index.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 5\n".to_vec(), vec![], "line 4: face 0: vertex 5 does not exist"),
        ("cage-nan.obj", b"v 0 nan 0\n".to_vec(), vec![], "three finite coordinates"),
        ("cage-crease.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nt crease 2/1/0 0 9 1.0\n".to_vec(), vec![], "line 5: tag crease: edge 0–9"),
        ("cage-chaikin.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nt creasemethod 0/0/1 chaikin\n".to_vec(), vec![], "line 5: tag creasemethod: crease method `chaikin`"),
        ("cage-repeat.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 1\n".to_vec(), vec![], "line 4: face 0: vertex 1 appears twice"),
    ]
}

#[test]
fn malformed_inputs_exit_2_with_a_specific_error() {
    let dir = tempfile::tempdir().unwrap();
    let all = cases();
    assert!(all.len() >= 50, "{} cases", all.len());
    let mut failures = Vec::new();
    for (name, content, extra, says) in all {
        std::fs::write(dir.path().join(name), &content).unwrap();
        let (command, output) = if [".csv", ".json", ".dxf"].iter().any(|e| name.ends_with(e)) {
            ("contours", "out.ply")
        } else if name.starts_with("cage-") {
            ("subdivide", "out.obj")
        } else if [".ply", ".obj", ".stl", ".off", ".glb"]
            .iter()
            .any(|e| name.ends_with(e))
        {
            ("render", "out.png")
        } else {
            ("extract", "out.ply")
        };
        let mut args = vec![command, name, "-o", output];
        args.extend(&extra);
        let out = Command::new(env!("CARGO_BIN_EXE_isocube"))
            .args(&args)
            .current_dir(dir.path())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr).trim().to_string();
        let named =
            err.contains(name) || (!says.is_empty() && err.contains(says)) || name == "half.raw";
        let ok = out.status.code() == Some(2)
            && !err.contains("panicked")
            && named
            && err.contains(says)
            && !dir.path().join(output).exists();
        if !ok {
            failures.push(format!("{name}: exit {:?}: {err}", out.status.code()));
        }
        if std::env::var_os("SHOW").is_some() {
            eprintln!("CASE {name}: {err}");
        }
    }
    assert!(
        failures.is_empty(),
        "{} of the malformed inputs:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// A full disk, simulated by a file-size limit (`ulimit -f`, with SIGXFSZ ignored so that the
/// write fails with EFBIG as it would with ENOSPC): every writer fails with exit code 1, leaves
/// the existing target as it was and no temporary file behind.
#[test]
fn a_full_disk_leaves_the_target_untouched() {
    let dir = tempfile::tempdir().unwrap();
    let run = |args: &str| {
        Command::new("sh")
            .arg("-c")
            .arg(format!(
                "trap '' XFSZ; ulimit -f 4; exec '{}' {args}",
                env!("CARGO_BIN_EXE_isocube")
            ))
            .current_dir(dir.path())
            .output()
            .unwrap()
    };
    // Inputs first, without the limit.
    let ok = Command::new(env!("CARGO_BIN_EXE_isocube"))
        .args(["extract", "sample:torus:40", "-o", "torus.ply", "--quiet"])
        .current_dir(dir.path())
        .status()
        .unwrap();
    assert!(ok.success());
    // A ball of radius 12 in a 40³ field, stored a[z, y, x] (C order, x fastest).
    let n = 40usize;
    let mut data = Vec::with_capacity(4 * n * n * n);
    for p in 0..n * n * n {
        let c = [p % n, p / n % n, p / (n * n)].map(|c| c as f32 - 19.5);
        data.extend_from_slice(&(c.iter().map(|x| x * x).sum::<f32>().sqrt() - 12.0).to_le_bytes());
    }
    let npy = npy("<f4", &format!("({n}, {n}, {n})"), &data);
    std::fs::write(dir.path().join("ball.npy"), npy).unwrap();
    for (command, target) in [
        ("extract sample:sphere:40 -o out.ply", "out.ply"),
        ("extract sample:sphere:40 -o out.glb", "out.glb"),
        ("extract ball.npy -o out.ply --stream", "out.ply"),
        (
            "extract sample:sphere:40 -o out.vtp --method ternary",
            "out.vtp",
        ),
        ("render torus.ply -o out.png", "out.png"),
        ("quality torus.ply --histogram out.png", "out.png"),
        ("subdivide torus.ply -o out.obj --levels 1", "out.obj"),
        ("contours sample:orebody -o out.ply", "out.ply"),
    ] {
        std::fs::write(dir.path().join(target), b"precious").unwrap();
        let before: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        let out = run(command);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{command}: {err}");
        assert!(
            err.contains("too large") && err.contains(target),
            "{command}: {err}"
        );
        assert!(!err.contains("panicked"), "{command}: {err}");
        assert_eq!(
            std::fs::read(dir.path().join(target)).unwrap(),
            b"precious",
            "{command}"
        );
        let after: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(before.len(), after.len(), "{command} left {after:?}");
    }
}

/// NaN and infinite values: by default the cells touching them are skipped and counted in the
/// summary (the mesh gets a hole there); `--strict` refuses the volume with exit code 2 and
/// writes nothing, in memory or streamed.
#[test]
fn non_finite_values_are_counted_or_refused_with_strict() {
    let dir = tempfile::tempdir().unwrap();
    let n = 10usize;
    let mut values: Vec<f32> = Vec::new();
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let d = |c: usize| c as f32 - 4.5;
                values.push((d(i).powi(2) + d(j).powi(2) + d(k).powi(2)).sqrt() - 3.2);
            }
        }
    }
    let write = |name: &str, values: &[f32]| {
        let data: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        std::fs::write(dir.path().join(name), npy("<f4", "(10, 10, 10)", &data)).unwrap();
    };
    write("clean.npy", &values);
    // One NaN just outside the surface on the x axis through the middle, one +∞ far outside.
    let nan_at = 8 + n * (4 + n * 4);
    values[nan_at] = f32::NAN;
    values[0] = f32::INFINITY;
    write("holes.npy", &values);
    let run = |args: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_isocube"))
            .args(args)
            .current_dir(dir.path())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr).to_string();
        assert!(!err.contains("panicked"), "{err}");
        (out.status.code(), err)
    };
    let (code, err) = run(&["extract", "holes.npy", "-o", "holes.ply"]);
    assert_eq!(code, Some(0), "{err}");
    // 8 cells around the NaN, 1 cell at the corner with +∞.
    assert!(err.contains("9 skipped for NaN/Inf values"), "{err}");
    assert!(err.contains("boundary edges"), "{err}");
    let (code, err) = run(&["info", "holes.ply", "--json"]);
    assert_eq!(code, Some(0), "{err}");
    for args in [
        vec!["extract", "holes.npy", "-o", "strict.ply", "--strict"],
        vec![
            "extract",
            "holes.npy",
            "-o",
            "strict.ply",
            "--strict",
            "--method",
            "ternary",
        ],
        vec![
            "extract",
            "holes.npy",
            "-o",
            "strict.ply",
            "--strict",
            "--stream",
        ],
    ] {
        let (code, err) = run(&args);
        assert_eq!(code, Some(2), "{args:?}: {err}");
        assert!(
            err.contains("holes.npy: 9 cells touch NaN or infinite values")
                && err.contains("nothing written (--strict)"),
            "{err}"
        );
        if !args.contains(&"--stream") {
            assert!(err.contains("the first at point (0, 0, 0)"), "{err}");
        }
        assert!(!dir.path().join("strict.ply").exists());
    }
    let (code, err) = run(&["extract", "clean.npy", "-o", "clean.ply", "--strict"]);
    assert_eq!(code, Some(0), "{err}");
    assert!(
        err.contains("watertight") && !err.contains("skipped"),
        "{err}"
    );
    // Nothing but the inputs and the two meshes: no temporary file left by the refusals.
    let mut names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["clean.npy", "clean.ply", "holes.npy", "holes.ply"]);
}

/// No command writes over one of its inputs, whether the output names it directly, through a
/// symbolic link or as a hard link: exit code 2 and the input unchanged.
#[cfg(unix)]
#[test]
fn outputs_never_replace_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let path = |name: &str| dir.path().join(name);
    let run = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_isocube"))
            .args(args)
            .current_dir(dir.path())
            .output()
            .unwrap()
    };
    // Inputs: a raw volume, a mesh and a cage, a contour file.
    let raw: Vec<u8> = (0..64u8).map(|v| if v == 21 { 9 } else { 0 }).collect();
    std::fs::write(path("v.raw"), &raw).unwrap();
    let ok = run(&["extract", "sample:sphere:8", "-o", "m.ply"]);
    assert!(ok.status.success());
    let ok = run(&["subdivide", "sample:cube", "--levels", "0", "-o", "c.obj"]);
    assert!(ok.status.success());
    std::fs::write(
        path("s.csv"),
        "section,z,contour,x,y\na,0,o,0,0\na,0,o,1,0\na,0,o,1,1\na,0,o,0,0\nb,1,o,0,0\nb,1,o,1,0\nb,1,o,1,1\nb,1,o,0,0\n",
    )
    .unwrap();
    std::fs::hard_link(path("v.raw"), path("hard.ply")).unwrap();
    let symlink =
        |target: &str, name: &str| std::os::unix::fs::symlink(path(target), path(name)).unwrap();
    symlink("m.ply", "to-mesh.png");
    symlink("m.ply", "to-mesh.svg");
    symlink("c.obj", "to-cage.obj");
    symlink("s.csv", "to-csv.ply");
    symlink("v.raw", "to-raw.ply");
    let raw_args = ["--dims", "4,4,4", "--type", "u8", "--level", "4"];
    let cases: Vec<(Vec<&str>, &str, &str)> = vec![
        (
            [&["extract", "v.raw", "-o", "hard.ply"], &raw_args[..]].concat(),
            "v.raw",
            "input volume",
        ),
        (
            [&["extract", "v.raw", "-o", "to-raw.ply"], &raw_args[..]].concat(),
            "v.raw",
            "input volume",
        ),
        (
            [
                &[
                    "extract",
                    "sample:sphere:4",
                    "--values",
                    "v.raw",
                    "-o",
                    "to-raw.ply",
                ],
                &raw_args[..2],
            ]
            .concat(),
            "v.raw",
            "--values volume",
        ),
        (
            vec!["subdivide", "c.obj", "-o", "c.obj"],
            "c.obj",
            "input mesh",
        ),
        (
            vec!["subdivide", "c.obj", "-o", "to-cage.obj"],
            "c.obj",
            "input mesh",
        ),
        (
            vec!["render", "m.ply", "-o", "to-mesh.png"],
            "m.ply",
            "mesh",
        ),
        (
            vec!["quality", "m.ply", "--histogram", "to-mesh.svg"],
            "m.ply",
            "mesh",
        ),
        (
            vec!["contours", "s.csv", "-o", "to-csv.ply"],
            "s.csv",
            "input",
        ),
    ];
    for (args, input, what) in cases {
        let before = std::fs::read(path(input)).unwrap();
        let out = run(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(
            err.contains(&format!("the output would overwrite the {what}")),
            "{args:?}: {err}"
        );
        assert_eq!(std::fs::read(path(input)).unwrap(), before, "{args:?}");
    }
}

/// Broken DICOM series (a folder): a cut slice, a transfer syntax isocube does not know, a pixel data
/// element declaring 2 GiB, a missing slice and a repeated one. Each exits with code 2, names
/// the slice file and says what is wrong, and writes nothing.
#[test]
fn broken_dicom_series_exit_2() {
    let fixture =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/volumes/dicom");
    let first = std::fs::read(fixture.join("slice-03-7.dcm")).unwrap();
    assert_eq!(&first[272..291], b"1.2.840.10008.1.2.1");
    assert_eq!(&first[884..888], b"\xe0\x7f\x10\x00");
    let mut unknown = first.clone();
    unknown[272..291].copy_from_slice(b"1.2.840.10008.1.2.9");
    let mut liar = first.clone();
    liar[892..896].copy_from_slice(&0x7fff_fff0u32.to_le_bytes());
    // (what to do to the series, what the error says)
    type Change = Box<dyn Fn(&std::path::Path)>;
    let put = |bytes: Vec<u8>| -> Change {
        Box::new(move |d| std::fs::write(d.join("slice-03-7.dcm"), &bytes).unwrap())
    };
    let cases: Vec<(Change, &str)> = vec![
        (put(first[..700].to_vec()), "slice-03-7.dcm: byte 656: element (0020,0037) declares 86 bytes, only 36 remain (the file is cut short"),
        (put(unknown), "slice-03-7.dcm: header field 'TransferSyntaxUID': unsupported: transfer syntax 1.2.840.10008.1.2.9: isocube reads"),
        (put(liar), "slice-03-7.dcm: byte 884: element (7FE0,0010) declares 2147483632 bytes, only 240 remain"),
        (Box::new(|d| std::fs::remove_file(d.join("slice-07-3.dcm")).unwrap()), "uneven or repeated slices"),
        (Box::new(|d| { std::fs::copy(d.join("slice-03-7.dcm"), d.join("slice-99.dcm")).unwrap(); }), "uneven or repeated slices"),
    ];
    for (change, says) in cases {
        let dir = tempfile::tempdir().unwrap();
        let series = dir.path().join("series");
        std::fs::create_dir(&series).unwrap();
        for entry in std::fs::read_dir(&fixture).unwrap() {
            let p = entry.unwrap().path();
            std::fs::copy(&p, series.join(p.file_name().unwrap())).unwrap();
        }
        change(&series);
        let out = Command::new(env!("CARGO_BIN_EXE_isocube"))
            .args(["extract", "series", "--level", "400", "-o", "out.ply"])
            .current_dir(dir.path())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{says}: {err}");
        assert!(
            err.contains(says) && !err.contains("panicked"),
            "{says}: {err}"
        );
        assert!(!dir.path().join("out.ply").exists());
    }
}

/// Resolutions that would exhaust memory are refused at once, with exit code 2, before any work:
/// a contour grid far finer than the body, a sample larger than the limit, subdivision past the
/// face limit, a picture too large.
#[test]
fn absurd_resolutions_are_refused_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let cases: [(&[&str], &str); 4] = [
        (
            &[
                "contours",
                "sample:orebody",
                "--cell",
                "0.00001",
                "-o",
                "o.ply",
            ],
            "would make about 1.18e14 triangles",
        ),
        (
            &[
                "extract",
                "sample:sphere:1024",
                "--max-memory",
                "1G",
                "-o",
                "s.ply",
            ],
            "its values need 4.0 GiB, more than the limit of 1.0 GiB",
        ),
        (
            &["subdivide", "sample:boss", "--levels", "30", "-o", "b.ply"],
            "at most 268435456 are supported",
        ),
        (
            &[
                "render",
                "missing.ply",
                "--size",
                "100000x100000",
                "-o",
                "r.png",
            ],
            "each 1 to 16384 pixels",
        ),
    ];
    for (args, says) in cases {
        let out = Command::new(env!("CARGO_BIN_EXE_isocube"))
            .args(args)
            .current_dir(dir.path())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }
}
