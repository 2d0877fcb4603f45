//! A compressed volume read plane by plane as extraction asks for them: the file is inflated
//! once, in order, and only the planes in work are held. What the mapped view
//! ([`crate::MappedVolume`]) does for files stored plain, this does for a gzipped NIfTI: the
//! whole grid is never in memory.

use std::collections::VecDeque;
use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{channel, sync_channel, Receiver, Sender};
use std::sync::Mutex;

use isocube::field::{Orientation, PlaneSource};

use super::mapped::Placement;
use super::raw::decode_into;
use super::{IoError, Position, VolumeOptions};

/// A gzipped NIfTI volume (`.nii.gz`) as a [`PlaneSource`]: planes are inflated in order as
/// they are first asked for and dropped when [`PlaneSource::release_before`] says so, so the
/// memory held is a few planes, whatever the volume's size. Planes must be asked for in
/// non-decreasing order of their first plane, less the overlap of what was not released, as
/// [`isocube::extract::extract_streamed`] does.
///
/// A read error (corrupt data, a file ending early) cannot be returned by `read_planes`: the
/// planes from there on read as NaN, and [`InflatingVolume::take_error`] tells what happened. Check
/// it before using what was made from the planes.
///
/// ```no_run
/// use isocube::extract::{extract_streamed, ExtractOptions};
/// use isocube::mesh::Mesh;
/// use isocube_io::{InflatingVolume, VolumeOptions};
/// let path = std::path::Path::new("head.nii.gz");
/// let volume = InflatingVolume::try_open(path, &VolumeOptions::default())?.expect("a NIfTI");
/// let mut mesh = Mesh::new();
/// extract_streamed(&volume, &ExtractOptions::default(), &mut mesh, &mut isocube::no_progress)
///     .expect("extracted");
/// if let Some(e) = volume.take_error() {
///     return Err(e.into());
/// }
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct InflatingVolume {
    path: PathBuf,
    placement: Placement,
    state: Mutex<Planes>,
}

/// The planes inflated and not yet released, as stored (decoded when copied out), and the
/// channel more come from.
struct Planes {
    incoming: Receiver<std::io::Result<Vec<u8>>>,
    /// Released planes' buffers, handed back to the inflater to fill again.
    spent: Sender<Vec<u8>>,
    /// Number of the first held plane.
    first: usize,
    held: VecDeque<Vec<u8>>,
    error: Option<IoError>,
    /// An error was met (and may have been taken).
    failed: bool,
}

/// Stored bytes inflated ahead of the planes in work: enough to keep the inflater busy while a
/// batch of slabs is meshed, little next to the volume.
const AHEAD_BYTES: usize = 4 << 20;

impl InflatingVolume {
    /// The volume at `path` when it is a single-file gzipped NIfTI that can be read plane by
    /// plane (one 3-d volume; every type the mapped view reads), `None` otherwise: read that
    /// file whole instead. `--spacing` and `--origin` in `options` override the header's.
    /// Errors are those of reading the file whole: a malformed header, or a volume past
    /// `options.max_memory`.
    ///
    /// Volumes under [`InflatingVolume::MIN_POINTS`] points are `None` too: read whole, they
    /// take little memory and start faster (no thread to start).
    pub fn try_open(
        path: &Path,
        options: &VolumeOptions,
    ) -> Result<Option<InflatingVolume>, IoError> {
        Self::open_from(path, options, Self::MIN_POINTS)
    }

    /// [`InflatingVolume::try_open`] whatever the volume's size.
    pub fn open_any_size(
        path: &Path,
        options: &VolumeOptions,
    ) -> Result<Option<InflatingVolume>, IoError> {
        Self::open_from(path, options, 0)
    }

    /// Points below which a volume is better read whole (16 MiB of `f32`).
    pub const MIN_POINTS: usize = 1 << 22;

    fn open_from(
        path: &Path,
        options: &VolumeOptions,
        min_points: usize,
    ) -> Result<Option<InflatingVolume>, IoError> {
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
        if options.raw.is_some() || !name.to_ascii_lowercase().ends_with(".nii.gz") {
            return Ok(None);
        }
        // The checks of reading the file whole, limit included: the volume is taken only when
        // it could have been read (and is then read in less memory).
        super::nifti::check_size(path, super::Budget::new(options.max_memory))?;
        let file = File::open(path).map_err(|e| IoError::os(path, e))?;
        let mut stream = flate2::read::MultiGzDecoder::new(BufReader::new(file));
        let Some(mut placement) = super::nifti::read_head(path, &mut stream)? else {
            return Ok(None);
        };
        let points = isocube::field::Grid::point_count(placement.dims)
            .map_err(|e| IoError::grid(path, e))?;
        if points < min_points {
            return Ok(None);
        }
        placement.spacing = options.spacing.unwrap_or(placement.spacing);
        placement.origin = options.origin.unwrap_or(placement.origin);
        // The same checks as a grid's.
        isocube::field::Grid::new([2, 2, 2], vec![0.0; 8])
            .and_then(|g| g.with_spacing(placement.spacing))
            .and_then(|g| g.with_origin(placement.origin))
            .map_err(|e| IoError::grid(path, e))?;
        // Inflating is the slow part and runs on one core: a thread of its own does it, ahead
        // of the slabs, while the others mesh.
        let [nx, ny, nz] = placement.dims;
        let plane_bytes = nx * ny * placement.scalar.size();
        let (send, incoming) = sync_channel((AHEAD_BYTES / plane_bytes.max(1)).max(2));
        let (spent, recycled) = channel::<Vec<u8>>();
        std::thread::Builder::new()
            .name("inflate".into())
            .spawn(move || {
                for _ in 0..nz {
                    let mut plane = recycled.try_recv().unwrap_or_default();
                    plane.resize(plane_bytes, 0);
                    let read = stream.read_exact(&mut plane).map(|()| plane);
                    let failed = read.is_err();
                    // The receiver is gone when extraction stopped early: so does this.
                    if send.send(read).is_err() || failed {
                        return;
                    }
                }
            })
            .map_err(|e| IoError::os(path, e))?;
        Ok(Some(InflatingVolume {
            path: path.to_path_buf(),
            placement,
            state: Mutex::new(Planes {
                incoming,
                spent,
                first: 0,
                held: VecDeque::new(),
                error: None,
                failed: false,
            }),
        }))
    }

    /// The same volume in grid index space: spacing 1, origin 0, no direction.
    pub fn into_index_space(mut self) -> InflatingVolume {
        self.placement.spacing = [1.0; 3];
        self.placement.origin = [0.0; 3];
        self.placement.orientation = Orientation::IDENTITY;
        self
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The first error met while reading planes, if any (planes from there on read as NaN).
    /// The error is handed over: a second call answers `None`, and planes still read as NaN.
    pub fn take_error(&self) -> Option<IoError> {
        let mut planes = self.lock();
        let error = planes.error.take();
        if error.is_some() {
            planes.failed = true;
        }
        error
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Planes> {
        // A panic while holding the lock leaves planes that are whole or absent: usable.
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The next plane's stored bytes, or empty after an error (recorded).
    fn next_plane(&self, planes: &mut Planes) -> Vec<u8> {
        if planes.failed || planes.error.is_some() {
            return Vec::new();
        }
        match planes.incoming.recv() {
            Ok(Ok(plane)) => plane,
            Ok(Err(e)) => {
                planes.error = Some(super::nifti::stream_error(&self.path, e));
                Vec::new()
            }
            Err(_) => {
                planes.error = Some(IoError::format(
                    &self.path,
                    Position::File,
                    "the inflating thread stopped",
                ));
                Vec::new()
            }
        }
    }

    /// Plane `stored` as values, or NaN where it is missing.
    fn decode(&self, stored: &[u8], out: &mut [f32]) {
        let p = &self.placement;
        if stored.len() != out.len() * p.scalar.size() {
            out.fill(f32::NAN);
            return;
        }
        decode_into(stored, p.scalar, p.endian, out);
        if let Some((slope, intercept)) = p.scale {
            out.iter_mut().for_each(|v| *v = *v * slope + intercept);
        }
    }
}

impl PlaneSource for InflatingVolume {
    fn dims(&self) -> [usize; 3] {
        self.placement.dims
    }

    fn spacing(&self) -> [f64; 3] {
        self.placement.spacing
    }

    fn origin(&self) -> [f64; 3] {
        self.placement.origin
    }

    fn orientation(&self) -> Orientation {
        self.placement.orientation
    }

    fn read_planes(&self, first: usize, out: &mut [f32]) {
        let [nx, ny, _] = self.placement.dims;
        let plane = nx * ny;
        let mut planes = self.lock();
        if first < planes.first {
            // Released already: the stream cannot go back.
            planes.error.get_or_insert_with(|| {
                IoError::format(
                    &self.path,
                    Position::Field(format!("plane {first}")),
                    "a plane was asked for after it was released",
                )
            });
            out.fill(f32::NAN);
            return;
        }
        let wanted = out.len() / plane.max(1);
        while planes.first + planes.held.len() < first + wanted {
            let next = self.next_plane(&mut planes);
            planes.held.push_back(next);
        }
        let skip = first - planes.first;
        for (out, held) in out
            .chunks_exact_mut(plane)
            .zip(planes.held.iter().skip(skip))
        {
            self.decode(held, out);
        }
    }

    fn release_before(&self, plane: usize) {
        let mut planes = self.lock();
        while planes.first < plane {
            let Some(buffer) = planes.held.pop_front() else {
                break;
            };
            // The inflater may have finished: then the buffer is simply dropped.
            let _ = planes.spent.send(buffer);
            planes.first += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::read_volume_oriented;
    use isocube::extract::{extract, extract_streamed, ExtractOptions};
    use isocube::mesh::Mesh;

    fn data(name: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../tests/data/volumes")
            .join(name)
    }

    #[test]
    fn planes_are_the_readers_values_and_the_mesh_is_the_same() {
        for name in ["rotated.nii.gz", "labels.nii.gz"] {
            let path = data(name);
            let options = VolumeOptions::default();
            let (grid, orientation) = read_volume_oriented(&path, &options).unwrap();
            assert!(
                InflatingVolume::try_open(&path, &options)
                    .unwrap()
                    .is_none(),
                "small"
            );
            let volume = InflatingVolume::open_any_size(&path, &options)
                .unwrap()
                .unwrap();
            assert_eq!(volume.dims(), grid.dims(), "{name}");
            assert_eq!(volume.spacing(), grid.spacing(), "{name}");
            assert_eq!(volume.origin(), grid.origin(), "{name}");
            assert_eq!(volume.orientation(), orientation, "{name}");
            let [nx, ny, nz] = grid.dims();
            let mut all = vec![0.0f32; nx * ny * nz];
            volume.read_planes(0, &mut all);
            assert_eq!(all, grid.values(), "{name}");
            assert!(volume.take_error().is_none());
            // A fresh stream meshed slab by slab gives the mesh of the whole grid.
            let volume = InflatingVolume::open_any_size(&path, &options)
                .unwrap()
                .unwrap();
            let (min, max) = all
                .iter()
                .fold((f32::MAX, f32::MIN), |(a, b), &v| (a.min(v), b.max(v)));
            let options = ExtractOptions::default().with_level((min + max) / 2.0 + 0.25);
            let (expected, _) =
                extract(grid.view().with_orientation(orientation), &options).unwrap();
            let mut streamed = Mesh::new();
            extract_streamed(&volume, &options, &mut streamed, &mut isocube::no_progress).unwrap();
            assert!(!expected.triangles.is_empty(), "{name}");
            assert_eq!(streamed, expected, "{name}");
            assert!(volume.take_error().is_none());
        }
    }

    #[test]
    fn a_truncated_stream_is_an_error_and_its_planes_are_nan() {
        let bytes = std::fs::read(data("rotated.nii.gz")).unwrap();
        let mut inflated = Vec::new();
        flate2::read::MultiGzDecoder::new(&bytes[..])
            .read_to_end(&mut inflated)
            .unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("short.nii.gz");
        let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        std::io::Write::write_all(&mut gz, &inflated[..inflated.len() - 10]).unwrap();
        std::fs::write(&path, gz.finish().unwrap()).unwrap();
        let volume = InflatingVolume::open_any_size(&path, &VolumeOptions::default())
            .unwrap()
            .unwrap();
        let [nx, ny, nz] = volume.dims();
        let mut all = vec![0.0f32; nx * ny * nz];
        volume.read_planes(0, &mut all);
        assert!(all[nx * ny * (nz - 1)..].iter().all(|v| v.is_nan()));
        let error = volume.take_error().expect("an error").to_string();
        assert!(
            error.contains("short.nii.gz") && error.contains("ends inside its data"),
            "{error}"
        );
    }

    #[test]
    fn other_files_are_not_taken() {
        let options = VolumeOptions::default();
        for name in ["flipped.nii", "plain.mhd", "rotated.mha"] {
            assert!(InflatingVolume::open_any_size(&data(name), &options)
                .unwrap()
                .is_none());
        }
    }
}
