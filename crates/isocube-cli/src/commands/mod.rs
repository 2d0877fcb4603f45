//! One module per subcommand: its arguments, their conversion to library options, and the run.

pub(crate) mod contours;
pub(crate) mod demo;
pub(crate) mod extract;
pub(crate) mod info;
pub(crate) mod quality;
pub(crate) mod render;
pub(crate) mod subdivide;
pub(crate) mod tables;
pub(crate) mod tetmesh;
pub(crate) mod view;
