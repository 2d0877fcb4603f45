//! NumPy `.npy` volumes (format versions 1–3).
//!
//! # Axes
//! The meaning of an array's axes does not depend on its memory order. With the default
//! [`NpyAxes::Xyz`], element `a[i, j, k]` is the value at grid point `x = i, y = j, z = k` — the
//! convention of scikit-image's `marching_cubes` and of nibabel's `get_fdata()`. With
//! [`NpyAxes::Zyx`], `a[k, j, i]` is the value at `(i, j, k)` — the convention of arrays from
//! SimpleITK's `GetArrayFromImage` and of image stacks indexed by slice first. C-order and
//! Fortran-order files are both read under either convention; the data are reordered as needed.

use std::path::Path;
use std::str::FromStr;

use super::raw::{decode_into, Endian, ScalarType};
use super::{Budget, IoError, Position};
use isocube::field::Grid;

/// How the three axes of a `.npy` array map to x, y, z.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum NpyAxes {
    /// `a[x, y, z]`.
    #[default]
    Xyz,
    /// `a[z, y, x]`.
    Zyx,
}

impl FromStr for NpyAxes {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "xyz" => Ok(NpyAxes::Xyz),
            "zyx" => Ok(NpyAxes::Zyx),
            _ => Err(format!("unknown axis order '{s}': expected xyz or zyx")),
        }
    }
}

struct Header {
    scalar: ScalarType,
    endian: Endian,
    fortran: bool,
    shape: Vec<usize>,
    data_offset: usize,
}

/// Where an array's values are in a `.npy` file and how x, y, z map to them.
pub(super) struct Layout {
    pub(super) scalar: ScalarType,
    pub(super) endian: Endian,
    pub(super) dims: [usize; 3],
    /// Distance in elements between neighbours along x, y and z.
    pub(super) strides: [usize; 3],
    /// Byte offset of the first element.
    pub(super) data_offset: usize,
}

/// Reads a 3-D `.npy` array (unit spacing, zero origin).
pub fn read_npy(path: &Path, axes: NpyAxes) -> Result<Grid, IoError> {
    read_npy_within(path, axes, Budget::UNLIMITED)
}

pub(super) fn read_npy_within(path: &Path, axes: NpyAxes, budget: Budget) -> Result<Grid, IoError> {
    let bytes = budget.read_file(path)?;
    read_npy_bytes(path, &bytes, axes, budget)
}

/// [`read_npy_within`] on a file's bytes already in memory (`path` names it in errors and, for a
/// detached header, locates its data).
pub(super) fn read_npy_bytes(
    path: &Path,
    bytes: &[u8],
    axes: NpyAxes,
    budget: Budget,
) -> Result<Grid, IoError> {
    let layout = layout(path, bytes, axes)?;
    let [nx, ny, nz] = layout.dims;
    budget.check_values(
        path,
        Position::Field("shape".into()),
        bytes.len() as u64,
        nx * ny * nz,
    )?;
    let size = layout.scalar.size();
    let data = &bytes[layout.data_offset..];
    let [sx, sy, sz] = layout.strides;
    let mut values = Vec::with_capacity(nx * ny * nz);
    if sx == 1 {
        let mut row = vec![0.0f32; nx];
        for k in 0..nz {
            for j in 0..ny {
                let at = (j * sy + k * sz) * size;
                decode_into(
                    &data[at..at + nx * size],
                    layout.scalar,
                    layout.endian,
                    &mut row,
                );
                values.extend_from_slice(&row);
            }
        }
    } else {
        for k in 0..nz {
            for j in 0..ny {
                let row = j * sy + k * sz;
                for i in 0..nx {
                    let at = (row + i * sx) * size;
                    values.push(layout.scalar.decode(&data[at..at + size], layout.endian) as f32);
                }
            }
        }
    }
    Grid::new(layout.dims, values).map_err(|e| IoError::grid(path, e))
}

/// Parses the header of a `.npy` file's bytes and checks the data fit it.
pub(super) fn layout(path: &Path, bytes: &[u8], axes: NpyAxes) -> Result<Layout, IoError> {
    let h = parse_header(path, bytes)?;
    if h.shape.len() != 3 {
        return Err(IoError::unsupported(
            path,
            Position::Field("shape".into()),
            format!("a 3-D array is needed, this one has shape {:?}", h.shape),
        ));
    }
    let shape = [h.shape[0], h.shape[1], h.shape[2]];
    let dims = match axes {
        NpyAxes::Xyz => shape,
        NpyAxes::Zyx => [shape[2], shape[1], shape[0]],
    };
    let count = Grid::point_count(dims).map_err(|e| IoError::grid(path, e))?;
    let size = h.scalar.size();
    let data_len = bytes.len() - h.data_offset;
    let need = count
        .checked_mul(size)
        .ok_or_else(|| IoError::format(path, Position::Field("shape".into()), "shape overflows"))?;
    if data_len != need {
        return Err(IoError::format(
            path,
            Position::Byte(h.data_offset as u64),
            format!(
                "shape {:?} of {} needs {need} data bytes, the file has {}",
                h.shape, h.scalar, data_len
            ),
        ));
    }
    // Memory stride of each array axis, in elements.
    let strides = if h.fortran {
        [1, shape[0], shape[0] * shape[1]]
    } else {
        [shape[1] * shape[2], shape[2], 1]
    };
    let strides = match axes {
        NpyAxes::Xyz => strides,
        NpyAxes::Zyx => [strides[2], strides[1], strides[0]],
    };
    Ok(Layout {
        scalar: h.scalar,
        endian: h.endian,
        dims,
        strides,
        data_offset: h.data_offset,
    })
}

fn parse_header(path: &Path, bytes: &[u8]) -> Result<Header, IoError> {
    let bad = |at: u64, reason: &str| IoError::format(path, Position::Byte(at), reason);
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Err(bad(0, "not a .npy file (missing the \\x93NUMPY magic)"));
    }
    let major = bytes[6];
    let (len, start) = match major {
        1 => (
            usize::from(u16::from_le_bytes([bytes[8], bytes[9]])),
            10usize,
        ),
        2 | 3 => {
            if bytes.len() < 12 {
                return Err(bad(8, "truncated header length"));
            }
            (
                u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
                12,
            )
        }
        v => {
            return Err(IoError::unsupported(
                path,
                Position::Byte(6),
                format!("format version {v}"),
            ))
        }
    };
    let end = start
        .checked_add(len)
        .filter(|&e| e <= bytes.len())
        .ok_or_else(|| bad(start as u64, "header runs past the end of the file"))?;
    let text = std::str::from_utf8(&bytes[start..end])
        .map_err(|_| bad(start as u64, "header is not valid text"))?;
    let field = |name: &str| -> Result<&str, IoError> {
        let key = format!("'{name}'");
        let at = text.find(&key).ok_or_else(|| {
            IoError::format(
                path,
                Position::Field(name.into()),
                "missing from the header",
            )
        })?;
        let rest = text[at + key.len()..].trim_start();
        rest.strip_prefix(':').map(str::trim_start).ok_or_else(|| {
            IoError::format(
                path,
                Position::Field(name.into()),
                "expected ':' after the key",
            )
        })
    };
    let descr_text = field("descr")?;
    let quote = descr_text
        .chars()
        .next()
        .filter(|c| *c == '\'' || *c == '"');
    let descr = quote
        .and_then(|q| descr_text[1..].split(q).next())
        .ok_or_else(|| {
            IoError::format(
                path,
                Position::Field("descr".into()),
                "expected a quoted dtype",
            )
        })?;
    let (endian, scalar) = parse_descr(descr).ok_or_else(|| {
        IoError::unsupported(
            path,
            Position::Field("descr".into()),
            format!("dtype '{descr}' (integers, floats of 4 or 8 bytes, booleans are read)"),
        )
    })?;
    let fortran_text = field("fortran_order")?;
    let fortran = if fortran_text.starts_with("True") {
        true
    } else if fortran_text.starts_with("False") {
        false
    } else {
        return Err(IoError::format(
            path,
            Position::Field("fortran_order".into()),
            "expected True or False",
        ));
    };
    let shape_text = field("shape")?;
    let inner = shape_text
        .strip_prefix('(')
        .and_then(|s| s.split(')').next())
        .ok_or_else(|| {
            IoError::format(path, Position::Field("shape".into()), "expected a tuple")
        })?;
    let shape = inner
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| {
            s.trim_end_matches('L').parse::<usize>().map_err(|_| {
                IoError::format(
                    path,
                    Position::Field("shape".into()),
                    format!("'{s}' is not a size"),
                )
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(Header {
        scalar,
        endian,
        fortran,
        shape,
        data_offset: end,
    })
}

fn parse_descr(d: &str) -> Option<(Endian, ScalarType)> {
    let mut chars = d.chars();
    let order = chars.next()?;
    let endian = match order {
        '<' | '|' | '=' => Endian::Little,
        '>' => Endian::Big,
        _ => return None,
    };
    if order == '=' && cfg!(target_endian = "big") {
        return Some((Endian::Big, parse_kind(&d[1..])?));
    }
    Some((endian, parse_kind(&d[1..])?))
}

fn parse_kind(k: &str) -> Option<ScalarType> {
    Some(match k {
        "u1" | "b1" => ScalarType::U8,
        "i1" => ScalarType::I8,
        "u2" => ScalarType::U16,
        "i2" => ScalarType::I16,
        "u4" => ScalarType::U32,
        "i4" => ScalarType::I32,
        "u8" => ScalarType::U64,
        "i8" => ScalarType::I64,
        "f4" => ScalarType::F32,
        "f8" => ScalarType::F64,
        _ => return None,
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use std::io::Write;

    /// Writes a .npy file the way NumPy does (version 1, header padded to 64 bytes).
    pub(crate) fn npy_bytes(descr: &str, fortran: bool, shape: &[usize], data: &[u8]) -> Vec<u8> {
        let shape_text = match shape.len() {
            1 => format!("({},)", shape[0]),
            _ => format!(
                "({})",
                shape
                    .iter()
                    .map(|s| s.to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        };
        let mut header = format!(
            "{{'descr': '{descr}', 'fortran_order': {}, 'shape': {shape_text}, }}",
            if fortran { "True" } else { "False" }
        );
        while (10 + header.len() + 1) % 64 != 0 {
            header.push(' ');
        }
        header.push('\n');
        let mut out = b"\x93NUMPY\x01\x00".to_vec();
        out.extend_from_slice(&(header.len() as u16).to_le_bytes());
        out.extend_from_slice(header.as_bytes());
        out.extend_from_slice(data);
        out
    }

    fn write(dir: &Path, name: &str, bytes: &[u8]) -> std::path::PathBuf {
        let p = dir.join(name);
        std::fs::File::create(&p).unwrap().write_all(bytes).unwrap();
        p
    }

    /// The value at (x, y, z) is 100x + 10y + z whatever the memory order and axis convention.
    #[test]
    fn c_and_fortran_orders_under_both_conventions() {
        let dir = tempfile::tempdir().unwrap();
        let (nx, ny, nz) = (4usize, 3usize, 2usize);
        let f = |x: usize, y: usize, z: usize| (100 * x + 10 * y + z) as f32;
        for axes in [NpyAxes::Xyz, NpyAxes::Zyx] {
            // Array shape in the chosen convention.
            let shape = match axes {
                NpyAxes::Xyz => [nx, ny, nz],
                NpyAxes::Zyx => [nz, ny, nx],
            };
            let value_at = |a: [usize; 3]| match axes {
                NpyAxes::Xyz => f(a[0], a[1], a[2]),
                NpyAxes::Zyx => f(a[2], a[1], a[0]),
            };
            for fortran in [false, true] {
                let mut data = Vec::new();
                let mut push = |a: [usize; 3]| data.extend_from_slice(&value_at(a).to_le_bytes());
                if fortran {
                    for a2 in 0..shape[2] {
                        for a1 in 0..shape[1] {
                            for a0 in 0..shape[0] {
                                push([a0, a1, a2]);
                            }
                        }
                    }
                } else {
                    for a0 in 0..shape[0] {
                        for a1 in 0..shape[1] {
                            for a2 in 0..shape[2] {
                                push([a0, a1, a2]);
                            }
                        }
                    }
                }
                let p = write(
                    dir.path(),
                    "v.npy",
                    &npy_bytes("<f4", fortran, &shape, &data),
                );
                let g = read_npy(&p, axes).unwrap();
                assert_eq!(g.dims(), [nx, ny, nz]);
                for z in 0..nz {
                    for y in 0..ny {
                        for x in 0..nx {
                            assert_eq!(g.value(x, y, z), f(x, y, z), "{axes:?} fortran={fortran}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn big_endian_integers() {
        let dir = tempfile::tempdir().unwrap();
        let data: Vec<u8> = (0..8i16).flat_map(|v| (v - 4).to_be_bytes()).collect();
        let p = write(
            dir.path(),
            "b.npy",
            &npy_bytes(">i2", false, &[2, 2, 2], &data),
        );
        let g = read_npy(&p, NpyAxes::Zyx).unwrap();
        assert_eq!(g.values(), &[-4.0, -3.0, -2.0, -1.0, 0.0, 1.0, 2.0, 3.0]);
    }

    #[test]
    fn malformed_files_are_rejected_with_position() {
        let dir = tempfile::tempdir().unwrap();
        let good = npy_bytes("<f4", false, &[2, 2, 2], &[0u8; 32]);
        let cases: Vec<(&str, Vec<u8>, &str)> = vec![
            ("magic", b"NOTNUMPYFILE".to_vec(), "magic"),
            ("truncated", good[..good.len() - 4].to_vec(), "data bytes"),
            (
                "dtype",
                npy_bytes("<c8", false, &[2, 2, 2], &[0u8; 64]),
                "dtype",
            ),
            ("2d", npy_bytes("<f4", false, &[4, 2], &[0u8; 32]), "3-D"),
            ("header", good[..20].to_vec(), "header"),
        ];
        for (name, bytes, needle) in cases {
            let p = write(dir.path(), &format!("{name}.npy"), &bytes);
            let err = read_npy(&p, NpyAxes::Xyz).unwrap_err().to_string();
            assert!(
                err.contains(needle) && err.contains(&format!("{name}.npy")),
                "{name}: {err}"
            );
        }
    }
}
