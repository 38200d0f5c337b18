//! Named geometric tolerances, each a fraction of the scene's bounding-box
//! diagonal (multiply by `Scene::diagonal`), so that nothing assumes a
//! unit box.

/// A point counts as in front of a plane only beyond this distance:
/// facing tests between patches, elements and clusters.
pub const FRONT: f64 = 1e-9;

/// Offset from a surface along its normal before casting a ray from it
/// (the exposure rays of the hierarchy's leaves).
pub const RAY_OFFSET: f64 = 1e-6;

/// Points this close are one point: the vertices along a contact line,
/// shared between a resting object's faces and the surface under it.
pub const COINCIDENT: f64 = 1e-6;

/// A leaf corner this close to a discontinuity segment moves onto it,
/// rather than making a sliver triangle beside it.
pub const SNAP: f64 = 2e-5;
