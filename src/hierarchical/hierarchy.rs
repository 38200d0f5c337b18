//! The element hierarchy of hierarchical radiosity \[HSA91\]: one quadtree per
//! input patch, in one arena addressed by [`ElementId`].
//!
//! Owns: elements (geometry, tree links, per-element solution state), the
//! quadtree split, and [`Hierarchy::validate`].
//!
//! Invariants (checked by [`Hierarchy::validate`]):
//! - Elements `0..patch_count` are the roots, element i on patch i.
//! - An element has no children or exactly four, stored contiguously from
//!   `first_child`; the children tile their parent (areas sum to the
//!   parent's within 1e-9 relative, corners shared as drawn below), lie on
//!   the parent's patch and keep its orientation (normal = patch normal).
//! - Ids are never reused or freed: an element, once split, stays split.
//! - Radiosities are finite; `exposure` is in [0, 1].
//!
//! Child order and corners (counter-clockwise seen from the front, as the
//! patch; `c` is the bilinear centre, `mij` the midpoint of edge i–j):
//!
//! ```text
//!  quad                               triangle
//!  p3 ---- m23 ---- p2                p2
//!   |   3   |   2   |                  | \
//!  m30 ---- c ---- m12                m20 --m12
//!   |   0   |   1   |                  | \ 3 | \
//!  p0 ---- m01 ---- p1                p0 --m01-- p1     (0 at p0, 1 at p1,
//!                                                        2 at p2, 3 = middle)
//!  child 0: p0 m01 c m30              child 0: p0 m01 m20
//!  child 1: m01 p1 m12 c              child 1: m01 p1 m12
//!  child 2: c m12 p2 m23              child 2: m20 m12 p2
//!  child 3: m30 c m23 p3              child 3: m01 m12 m20
//! ```

use glam::DVec3;

use crate::scene::{Scene, Shape, polygon_area_normal, polygon_centroid};
use crate::util::geometry::outside_polygon;

/// Index of an element in a [`Hierarchy`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct ElementId(pub u32);

impl ElementId {
    /// The arena index.
    pub fn index(self) -> usize {
        self.0 as usize
    }
}

/// No element (a root's parent, a leaf's first child).
const NONE: u32 = u32::MAX;

/// One node of a patch's quadtree.
#[derive(Clone, Debug, PartialEq)]
pub struct Element {
    /// 3 or 4 corners (see `shape`), counter-clockwise; for a triangle the
    /// fourth repeats the third.
    pub corners: [DVec3; 4],
    /// Area (m²).
    pub area: f64,
    /// Radiosity B: at a leaf E + ρ H; above, the area-weighted mean of the
    /// children (after push-pull).
    pub radiosity: DVec3,
    /// Mean radiosity over the element's exposed part: what a link from
    /// it carries. Area inside a closed solid (a floor under a box) is
    /// dark and seen by nothing; averaging it in would dim every link
    /// from the element twice, once by visibility and once by the mean.
    pub exposed_radiosity: DVec3,
    /// Fraction of the area that is exposed, in [0, 1] (1 until the solver
    /// measures it; above the leaves, the area-weighted mean of the
    /// children's after push-pull).
    pub exposure: f32,
    /// The patch the element lies on.
    pub patch: u32,
    parent: u32,
    first_child: u32,
    /// Triangle or quad, as its patch.
    pub shape: Shape,
    /// 0 for a root.
    pub depth: u8,
}

impl Element {
    /// The 3 or 4 corners.
    pub fn vertices(&self) -> &[DVec3] {
        match self.shape {
            Shape::Triangle => &self.corners[..3],
            Shape::Quad => &self.corners[..4],
        }
    }

    /// Area-weighted centroid.
    pub fn centroid(&self) -> DVec3 {
        polygon_centroid(self.vertices())
    }

    /// True when the element has not been split.
    pub fn is_leaf(&self) -> bool {
        self.first_child == NONE
    }

    /// The four children, if split.
    pub fn children(&self) -> Option<[ElementId; 4]> {
        (self.first_child != NONE).then(|| {
            let f = self.first_child;
            [f, f + 1, f + 2, f + 3].map(ElementId)
        })
    }

    /// The parent, unless this is a root.
    pub fn parent(&self) -> Option<ElementId> {
        (self.parent != NONE).then_some(ElementId(self.parent))
    }
}

/// The corners of the four children of a polygon, in the order of the module
/// doc.
pub fn split_corners(shape: Shape, c: &[DVec3; 4]) -> [[DVec3; 4]; 4] {
    let mid = |a: DVec3, b: DVec3| 0.5 * (a + b);
    match shape {
        Shape::Quad => {
            let [p0, p1, p2, p3] = *c;
            let (m01, m12, m23, m30) = (mid(p0, p1), mid(p1, p2), mid(p2, p3), mid(p3, p0));
            let centre = 0.25 * (p0 + p1 + p2 + p3);
            [
                [p0, m01, centre, m30],
                [m01, p1, m12, centre],
                [centre, m12, p2, m23],
                [m30, centre, m23, p3],
            ]
        }
        Shape::Triangle => {
            let [p0, p1, p2, _] = *c;
            let (m01, m12, m20) = (mid(p0, p1), mid(p1, p2), mid(p2, p0));
            [
                [p0, m01, m20, m20],
                [m01, p1, m12, m12],
                [m20, m12, p2, p2],
                [m01, m12, m20, m20],
            ]
        }
    }
}

fn area_of(shape: Shape, c: &[DVec3; 4]) -> f64 {
    let n = if shape == Shape::Quad { 4 } else { 3 };
    polygon_area_normal(&c[..n]).0
}

/// What the oracle needs to know of a link's source beyond its geometry.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SourceState {
    /// Its radiosity (the mean over it, for a split element).
    pub radiosity: DVec3,
    /// How much its radiosity varies across it (twice the standard
    /// deviation over its leaves, per channel; zero for a leaf): the link
    /// hands the receiver the mean, however the kernel weighs the source's
    /// parts.
    pub unevenness: DVec3,
}

/// All quadtrees of a scene.
#[derive(Clone, Debug)]
pub struct Hierarchy {
    /// The arena: roots (one per patch, patch order) first, then children in creation order.
    pub elements: Vec<Element>,
    /// Patch count: elements `0..roots` are the roots.
    roots: usize,
}

impl Hierarchy {
    /// One root element per patch of `scene`, radiosity = emission.
    pub fn new(scene: &Scene) -> Hierarchy {
        let elements = scene
            .patches
            .iter()
            .enumerate()
            .map(|(i, p)| Element {
                corners: p.corners,
                area: p.area,
                radiosity: p.emission,
                exposed_radiosity: p.emission,
                exposure: 1.0,
                patch: i as u32,
                parent: NONE,
                first_child: NONE,
                shape: p.shape,
                depth: 0,
            })
            .collect();
        Hierarchy {
            elements,
            roots: scene.patches.len(),
        }
    }

    /// Number of elements (all nodes).
    pub fn len(&self) -> usize {
        self.elements.len()
    }

    /// True when there is no element.
    pub fn is_empty(&self) -> bool {
        self.elements.is_empty()
    }

    /// The leaf of `patch`'s quadtree holding `x`: from the root, the
    /// child that `x` is least outside of (the first such, on a shared
    /// edge).
    pub fn leaf_at(&self, scene: &Scene, patch: usize, x: DVec3) -> ElementId {
        let normal = scene.patches[patch].normal;
        let mut id = self.root(patch);
        while let Some(kids) = self.get(id).children() {
            let mut best = (f64::INFINITY, kids[0]);
            for k in kids {
                let d = outside_polygon(self.get(k).vertices(), normal, x);
                if d < best.0 {
                    best = (d, k);
                }
            }
            id = best.1;
        }
        id
    }

    /// The root of patch `patch`.
    pub fn root(&self, patch: usize) -> ElementId {
        ElementId(patch as u32)
    }

    /// Number of roots (= patches).
    pub fn root_count(&self) -> usize {
        self.roots
    }

    /// The element `id`.
    pub fn get(&self, id: ElementId) -> &Element {
        &self.elements[id.index()]
    }

    /// Number of leaves.
    pub fn leaf_count(&self) -> usize {
        self.elements.iter().filter(|e| e.is_leaf()).count()
    }

    /// Ids of all leaves, in arena order.
    pub fn leaves(&self) -> impl Iterator<Item = ElementId> + '_ {
        self.elements
            .iter()
            .enumerate()
            .filter(|(_, e)| e.is_leaf())
            .map(|(i, _)| ElementId(i as u32))
    }

    /// Splits `id` into four children (no-op if already split) and returns
    /// them. Children start with their parent's radiosity.
    pub fn split(&mut self, id: ElementId) -> [ElementId; 4] {
        if let Some(children) = self.get(id).children() {
            return children;
        }
        let first = self.elements.len() as u32;
        let parent = self.get(id).clone();
        for corners in split_corners(parent.shape, &parent.corners) {
            self.elements.push(Element {
                area: area_of(parent.shape, &corners),
                corners,
                radiosity: parent.radiosity,
                exposed_radiosity: parent.exposed_radiosity,
                exposure: 1.0,
                patch: parent.patch,
                parent: id.0,
                first_child: NONE,
                shape: parent.shape,
                depth: parent.depth.saturating_add(1),
            });
        }
        self.elements[id.index()].first_child = first;
        [first, first + 1, first + 2, first + 3].map(ElementId)
    }

    /// What a link's oracle needs of source `id`: the radiosity its links
    /// carry (the exposed part's) and how much its children's differ.
    pub fn source_state(&self, id: ElementId) -> SourceState {
        let e = self.get(id);
        let unevenness = e.children().map_or(DVec3::ZERO, |kids| {
            let b = kids.map(|k| self.get(k).exposed_radiosity);
            let lo = b.iter().fold(DVec3::INFINITY, |a, x| a.min(*x));
            let hi = b.iter().fold(DVec3::NEG_INFINITY, |a, x| a.max(*x));
            hi - lo
        });
        SourceState {
            radiosity: e.exposed_radiosity,
            unevenness,
        }
    }

    /// Bytes held by the arena (capacity included).
    pub fn memory_bytes(&self) -> usize {
        self.elements.capacity() * std::mem::size_of::<Element>()
    }

    /// Checks the invariants of the module doc against `scene`; the first
    /// violation is returned as a message.
    pub fn validate(&self, scene: &Scene) -> Result<(), String> {
        if self.roots != scene.patches.len() || self.elements.len() < self.roots {
            return Err("root count differs from the patch count".into());
        }
        for (i, e) in self.elements.iter().enumerate() {
            let patch = &scene.patches[e.patch as usize];
            if (i < self.roots) != (e.parent == NONE) {
                return Err(format!("element {i}: root/parent mismatch"));
            }
            if e.shape != patch.shape {
                return Err(format!("element {i}: shape differs from its patch"));
            }
            let (area, normal) = polygon_area_normal(e.vertices());
            if (area - e.area).abs() > 1e-9 * e.area.max(f64::MIN_POSITIVE) {
                return Err(format!("element {i}: stored area {} ≠ {area}", e.area));
            }
            if normal.dot(patch.normal) < 1.0 - 1e-9 {
                return Err(format!("element {i}: normal differs from its patch"));
            }
            if !e.radiosity.is_finite() || !e.exposed_radiosity.is_finite() {
                return Err(format!("element {i}: non-finite radiosity"));
            }
            if !(0.0..=1.0).contains(&e.exposure) {
                return Err(format!(
                    "element {i}: exposure {} outside [0, 1]",
                    e.exposure
                ));
            }
            let Some(children) = e.children() else {
                continue;
            };
            if children.iter().any(|c| c.index() >= self.elements.len()) {
                return Err(format!("element {i}: child out of range"));
            }
            let expected = split_corners(e.shape, &e.corners);
            let mut sum = 0.0;
            for (k, c) in children.iter().enumerate() {
                let child = self.get(*c);
                if child.parent != i as u32 || child.patch != e.patch {
                    return Err(format!("element {i}: child {k} has another parent"));
                }
                if child.corners != expected[k] {
                    return Err(format!("element {i}: child {k} corners inconsistent"));
                }
                sum += child.area;
            }
            if (sum - e.area).abs() > 1e-9 * e.area {
                return Err(format!(
                    "element {i}: children areas sum to {sum}, parent {}",
                    e.area
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn children_tile_quads_and_triangles() {
        let quad = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(2.5, 1.0, 0.0),
            DVec3::new(-0.3, 1.2, 0.0),
        ];
        let tri = [
            DVec3::ZERO,
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(0.2, 1.0, 0.0),
            DVec3::new(0.2, 1.0, 0.0),
        ];
        for (shape, c) in [(Shape::Quad, quad), (Shape::Triangle, tri)] {
            let whole = area_of(shape, &c);
            let kids = split_corners(shape, &c);
            let sum: f64 = kids.iter().map(|k| area_of(shape, k)).sum();
            assert!((sum - whole).abs() < 1e-12 * whole, "{shape:?}");
            for k in &kids {
                let n = if shape == Shape::Quad { 4 } else { 3 };
                let (_, normal) = polygon_area_normal(&k[..n]);
                assert!((normal - DVec3::Z).length() < 1e-12, "orientation kept");
            }
        }
    }
}
