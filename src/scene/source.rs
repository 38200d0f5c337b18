//! What a bake needs of the input file besides its triangles: the glTF
//! document's structure (node tree, transforms, cameras, materials and their
//! textures) and where each triangle came from in it.
//!
//! Owns: [`SourceDocument`], [`TriangleOrigin`] and interpolating an
//! origin's texture coordinates on a patch. The document is kept as
//! glTF JSON (the format the bake writes back), with its geometry removed.
//!
//! Invariants:
//! - `json` has no meshes, accessors, buffer views, buffers, skins or
//!   animations; every other index but the images' (nodes, cameras,
//!   materials, textures, samplers) is the input's own, so a bake that
//!   copies these arrays keeps the input's indices.
//! - `json.images` are the images some texture uses (the others are left
//!   out, unread), renumbered in order, and the textures point at them;
//!   `images[i]` holds the encoded bytes of `json.images[i]` (PNG or JPEG,
//!   as the input had them), wherever the input kept them (URI, data URI,
//!   buffer view).
//! - `world[n]` is node `n`'s world transform when the loader reached it
//!   from the default scene, `None` otherwise.

use glam::{DMat4, DVec3, Vec2};
use gltf::json;

use super::SceneTriangle;

/// The input glTF document without its geometry.
#[derive(Clone, Debug)]
pub struct SourceDocument {
    /// The document: nodes, scenes, cameras, materials, textures, samplers
    /// and images as the input wrote them; see the module invariants.
    pub json: json::Root,
    /// Encoded bytes of each image of `json.images`.
    pub images: Vec<Vec<u8>>,
    /// World transform of every node reached from the default scene.
    pub world: Vec<Option<DMat4>>,
    /// The glTF material index of each of the scene's materials, by the
    /// scene's material index (`None`: glTF's default material).
    pub materials: Vec<Option<usize>>,
}

/// Where an input triangle came from within its surface (glTF node).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TriangleOrigin {
    /// Index of the primitive within the node's mesh.
    pub primitive: u32,
    /// The input's `TEXCOORD_0` at the three corners, in the order of the
    /// triangle's positions, when the primitive has that attribute.
    pub tex_coords: Option<[[f32; 2]; 3]>,
    /// The input's `TEXCOORD_1` (lightmap coordinates) likewise.
    pub lightmap_coords: Option<[[f32; 2]; 3]>,
}

/// A per-corner pair (texture coordinates) of a patch's `triangles`,
/// interpolated at `p`: in the triangle that contains `p` best (largest
/// least barycentric weight); `None` when a triangle lacks it.
pub fn interpolate_on_patch<'a>(
    triangles: impl Iterator<Item = &'a SceneTriangle>,
    p: DVec3,
    corners: impl Fn(&SceneTriangle) -> Option<[[f32; 2]; 3]>,
) -> Option<Vec2> {
    let mut best: Option<(f64, Vec2)> = None;
    for t in triangles {
        let values = corners(t)?;
        let [a, b, c] = t.positions;
        let n = (b - a).cross(c - a);
        let area2 = n.length_squared();
        if !(area2 > 0.0) {
            continue;
        }
        let w1 = (p - a).cross(c - a).dot(n) / area2;
        let w2 = (b - a).cross(p - a).dot(n) / area2;
        let w0 = 1.0 - w1 - w2;
        let inside = w0.min(w1).min(w2);
        if best.is_none_or(|(score, _)| inside > score) {
            let value = Vec2::from(values[0]) * w0 as f32
                + Vec2::from(values[1]) * w1 as f32
                + Vec2::from(values[2]) * w2 as f32;
            best = Some((inside, value));
        }
    }
    best.map(|(_, value)| value)
}
