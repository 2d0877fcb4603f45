//! Errors by stage, and one type that holds any of them.

use thiserror::Error;

/// Any error of the library, by the stage it comes from: what a front end (the command line,
/// the Python package, a cluster worker) matches on or converts once. File formats are the
/// `isocube-io` crate's (`IoError`), since this crate does no I/O.
///
/// ```
/// use isocube::extract::{extract, ExtractOptions};
/// use isocube::field::Grid;
/// fn mesh(values: Vec<f32>) -> Result<usize, isocube::Error> {
///     let grid = Grid::new([2, 2, 2], values)?;
///     let (mesh, _) = extract(&grid, &ExtractOptions::default())?;
///     Ok(mesh.triangle_count())
/// }
/// assert!(matches!(mesh(vec![0.0; 7]), Err(isocube::Error::Grid(_))));
/// assert_eq!(mesh(vec![-1.0, 1.0, -1.0, 1.0, -1.0, 1.0, -1.0, 1.0]).unwrap(), 2);
/// ```
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum Error {
    /// A grid or field view that cannot be built.
    #[error(transparent)]
    Grid(#[from] crate::field::GridError),
    /// Extraction (binary, ternary, labels, streamed).
    #[error(transparent)]
    Extract(#[from] crate::extract::ExtractError),
    /// Contour stacks and their reconstruction.
    #[error(transparent)]
    Contours(#[from] crate::contours::ContourError),
    /// A single contour loop.
    #[error(transparent)]
    Loop(#[from] crate::contours::LoopError),
    /// Polygon meshes and subdivision.
    #[error(transparent)]
    Subdiv(#[from] crate::subdiv::SubdivError),
    /// An indexed mesh that breaks its invariants.
    #[error(transparent)]
    Mesh(#[from] crate::mesh::MeshError),
    /// A name or option given as text.
    #[error(transparent)]
    Parse(#[from] ParseError),
}

/// A name or option given as text that is not one the library knows (a sample, a topology, a
/// triangulation, a view): what was read, the text, and why.
///
/// ```
/// use isocube::field::Sample;
/// let e = "sphre".parse::<Sample>().unwrap_err();
/// assert_eq!((e.what, e.input.as_str()), ("sample", "sphre"));
/// assert!(e.to_string().contains("expected one of sphere"));
/// ```
#[derive(Clone, Debug, Error, PartialEq, Eq)]
#[error("{message}")]
#[non_exhaustive]
pub struct ParseError {
    /// What was being read.
    pub what: &'static str,
    /// The text given.
    pub input: String,
    message: String,
}

impl ParseError {
    pub(crate) fn new(what: &'static str, input: &str, message: String) -> ParseError {
        ParseError {
            what,
            input: input.to_string(),
            message,
        }
    }
}

/// A progress callback for callers that neither watch nor stop the work.
///
/// ```
/// use isocube::extract::{extract_into, ExtractOptions};
/// use isocube::field::Sample;
/// use isocube::mesh::Mesh;
/// let mut mesh = Mesh::new();
/// let grid = Sample::Sphere.grid(10);
/// extract_into(&grid, &ExtractOptions::default(), &mut mesh, &mut isocube::no_progress).unwrap();
/// assert_eq!(mesh.triangle_count(), 524);
/// ```
pub fn no_progress(_done: usize, _total: usize) -> std::ops::ControlFlow<()> {
    std::ops::ControlFlow::Continue(())
}
