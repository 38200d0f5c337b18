//! Lightmaps: the output mesh's radiosity B and irradiance H as texture
//! atlases over a second set of texture coordinates.
//!
//! Owns: the atlas's texture coordinates per output vertex (the input's
//! `TEXCOORD_1` when every triangle has it, else generated: charts of
//! coplanar, edge-connected patches of one node and side, each projected
//! onto its plane, so no chart is distorted, packed by `etagere`), and the
//! texels, each evaluated at its surface point from the output mesh.
//!
//! Invariants:
//! - Texture space follows glTF: (0, 0) is the top-left corner of texel
//!   (0, 0), u runs right and v down; texel (x, y) is row y of the frames.
//! - Every texel within [`REACH`] texels of a triangle's footprint holds the
//!   value of the triangle's closest point (the nearest triangle wins; ties
//!   go to the earlier triangle): bilinear filtering anywhere on a triangle
//!   reads only its own chart's values, and a texel is never averaged
//!   between charts. Generated charts keep [`PADDING`] texels apart from
//!   their rectangle's edge, so the reach never crosses into a neighbour.
//! - Values are the mesh's own (B and H interpolated linearly within a
//!   triangle): the two sides of a seam read the vertices on their side,
//!   which are point evaluations of the solution at the same points.
//! - Deterministic: charts, packing and rasterisation follow the mesh's
//!   order.

use std::collections::HashMap;

use etagere::{AtlasAllocator, size2};
use glam::{DVec2, DVec3, Vec2, Vec3};

use crate::error::{Error, Result};
use crate::mesh::OutputMesh;
use crate::render::frame::Frame;
use crate::scene::{Scene, interpolate_on_patch};
use crate::util::geometry::position_key;
use crate::util::union_find::UnionFind;

/// Smallest and largest accepted atlas side, in texels.
pub const RESOLUTION_RANGE: (u32, u32) = (16, 16384);
/// Bytes the atlases hold per texel at most: B, H and the display
/// (12 each), the distance and written mask (9), their encodings (up to
/// 36), rounded up.
pub const BYTES_PER_TEXEL: u64 = 96;
/// Texels kept free around each generated chart's footprint.
const PADDING: u32 = 2;
/// How far from a triangle's footprint (in texels) its values are written:
/// more than √2 / 2 · 2, the farthest a bilinear tap lies from its point.
const REACH: f64 = 1.5;
/// Each failed packing shrinks the texel density by this factor ...
const SHRINK: f64 = 0.9;
/// ... at most this often (0.9¹⁰⁰ ≈ 3·10⁻⁵: a thousandth of the texels).
const MAX_SHRINKS: usize = 100;
/// Bisection steps between the last failure and the first fit.
const BISECTIONS: usize = 8;
/// Largest angle (radians) between normals of patches in one chart.
const COPLANAR_ANGLE: f64 = 1e-6;
/// Largest plane offset between patches in one chart, as a fraction of
/// the scene diagonal.
const COPLANAR_DISTANCE: f64 = 1e-7;

/// Where the atlas's texture coordinates came from.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize, schemars::JsonSchema,
)]
#[serde(rename_all = "snake_case")]
pub enum UvSource {
    /// The input's `TEXCOORD_1`, interpolated at each vertex.
    Input,
    /// Charts made here.
    Generated,
}

/// What building the atlas did, for the report.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
pub struct LightmapStats {
    /// Atlas side in texels.
    pub resolution: u32,
    /// Where the texture coordinates came from.
    pub uv_source: UvSource,
    /// Generated charts (0 with the input's coordinates).
    pub charts: usize,
    /// Texels per metre of the generated charts (0 with the input's).
    pub texels_per_metre: f64,
    /// Texels whose centre lies on a triangle, over all texels.
    pub efficiency: f64,
    /// Texels written (covered, or within reach of a triangle).
    pub written_texels: usize,
}

/// The atlases and the coordinates that address them.
#[derive(Clone, Debug)]
pub struct Lightmap {
    /// Texture coordinates per output vertex, in [0, 1]².
    pub uv: Vec<Vec2>,
    /// B per texel (W/m²).
    pub radiosity: Frame,
    /// H per texel (W/m²).
    pub irradiance: Frame,
    /// Per texel, row by row: whether it holds a value (covered by a
    /// triangle or within its reach); the others are zero.
    pub written: Vec<bool>,
    /// What building did.
    pub stats: LightmapStats,
}

/// `--lightmap RES`: a square atlas side within [`RESOLUTION_RANGE`].
pub fn check_resolution(resolution: u32) -> Result<()> {
    let (lo, hi) = RESOLUTION_RANGE;
    if (lo..=hi).contains(&resolution) {
        Ok(())
    } else {
        Err(Error::Setting(format!(
            "--lightmap {resolution} is out of range ({lo} to {hi} texels)"
        )))
    }
}

impl Lightmap {
    /// The atlases of `mesh` (an output mesh of `scene`), `resolution`
    /// texels square. Fails when the resolution is out of range, the mesh
    /// is not a valid mesh of `scene`, or the charts cannot be packed at any
    /// density.
    pub fn build(scene: &Scene, mesh: &OutputMesh, resolution: u32) -> Result<Lightmap> {
        check_resolution(resolution)?;
        if let Some(message) = mesh.length_mismatch() {
            return Err(Error::encode("the lightmap", message));
        }
        let n = mesh.vertex_count();
        if let Some(t) = mesh
            .triangles
            .iter()
            .position(|t| t.iter().any(|&v| v as usize >= n))
        {
            return Err(Error::encode(
                "the lightmap",
                format!("triangle {t} indexes beyond the {n} vertices"),
            ));
        }
        let (uv, uv_source, charts, density) = match input_uvs(scene, mesh) {
            Some(uv) => (uv, UvSource::Input, 0, 0.0),
            None => {
                let (uv, charts, density) = generated_uvs(scene, mesh, resolution)?;
                (uv, UvSource::Generated, charts, density)
            }
        };
        let mut raster = Raster::new(resolution);
        for tri in &mesh.triangles {
            raster.triangle(tri.map(|v| v as usize), &uv, mesh);
        }
        let texels = f64::from(resolution).powi(2);
        Ok(Lightmap {
            stats: LightmapStats {
                resolution,
                uv_source,
                charts,
                texels_per_metre: density,
                efficiency: raster.covered() as f64 / texels,
                written_texels: raster.written(),
            },
            uv,
            written: raster.distance.iter().map(|d| d.is_finite()).collect(),
            radiosity: raster.radiosity,
            irradiance: raster.irradiance,
        })
    }

    /// The radiosity atlas as display radiance B / π, for a PNG.
    pub fn display(&self) -> Frame {
        let mut frame = self.radiosity.clone();
        for p in &mut frame.pixels {
            *p = p.map(|c| c / std::f32::consts::PI);
        }
        frame
    }

    /// Bilinear lookup of `frame` at `uv` (clamped to the edge), as a
    /// viewer's sampler reads it.
    pub fn sample(frame: &Frame, uv: Vec2) -> Vec3 {
        let (w, h) = (frame.width as i64, frame.height as i64);
        let x = f64::from(uv.x) * w as f64 - 0.5;
        let y = f64::from(uv.y) * h as f64 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
        let texel = |i: i64, j: i64| {
            let (i, j) = (i.clamp(0, w - 1), j.clamp(0, h - 1));
            Vec3::from(frame.pixels[(j * w + i) as usize])
        };
        let (i, j) = (x0 as i64, y0 as i64);
        let top = texel(i, j).lerp(texel(i + 1, j), fx);
        let bottom = texel(i, j + 1).lerp(texel(i + 1, j + 1), fx);
        top.lerp(bottom, fy)
    }
}

/// The input's `TEXCOORD_1` at every vertex, when every patch's triangles
/// carry it.
fn input_uvs(scene: &Scene, mesh: &OutputMesh) -> Option<Vec<Vec2>> {
    mesh.patch
        .iter()
        .zip(&mesh.positions)
        .map(|(&p, &x)| {
            let patch = scene.patches.get(p as usize)?;
            let triangles = patch.triangles.iter().filter(|&&t| t != u32::MAX);
            interpolate_on_patch(
                triangles.map(|&t| &scene.triangles[t as usize]),
                x.as_dvec3(),
                |t| t.origin.lightmap_coords,
            )
        })
        .collect()
}

/// One chart: its plane's basis and the bounds of its vertices in the
/// plane (metres).
struct Chart {
    u: DVec3,
    v: DVec3,
    lo: DVec2,
    hi: DVec2,
}

/// Charts of coplanar, edge-connected patches of one surface and side,
/// packed into the atlas at the largest density that fits; returns the
/// per-vertex coordinates, the chart count and the density (texels per
/// metre).
fn generated_uvs(
    scene: &Scene,
    mesh: &OutputMesh,
    resolution: u32,
) -> Result<(Vec<Vec2>, usize, f64)> {
    let n_patches = scene.patches.len();
    let diagonal = scene.diagonal();
    let mut sets = UnionFind::new(n_patches);
    let mut edges: HashMap<([u64; 3], [u64; 3]), Vec<usize>> = HashMap::new();
    for (i, patch) in scene.patches.iter().enumerate() {
        let corners = patch.vertices();
        for k in 0..corners.len() {
            let (a, b) = (
                position_key(corners[k]),
                position_key(corners[(k + 1) % corners.len()]),
            );
            edges.entry((a.min(b), a.max(b))).or_default().push(i);
        }
    }
    let mut keys: Vec<_> = edges.keys().copied().collect();
    keys.sort_unstable();
    for key in keys {
        let sharing = &edges[&key];
        for (x, &i) in sharing.iter().enumerate() {
            for &j in &sharing[x + 1..] {
                let (p, q) = (&scene.patches[i], &scene.patches[j]);
                let same = p.surface == q.surface
                    && p.side == q.side
                    && p.normal.dot(q.normal) >= COPLANAR_ANGLE.cos()
                    && (q.corners[0] - p.corners[0]).dot(p.normal).abs()
                        <= COPLANAR_DISTANCE * diagonal;
                if same {
                    sets.union(i, j);
                }
            }
        }
    }
    // Chart per set representative, in patch order; bases from the
    // representative patch.
    let mut chart_of_patch = vec![usize::MAX; n_patches];
    let mut charts: Vec<Chart> = Vec::new();
    let mut chart_of_root: HashMap<usize, usize> = HashMap::new();
    for i in 0..n_patches {
        let root = sets.find(i);
        let c = *chart_of_root.entry(root).or_insert_with(|| {
            let p = &scene.patches[root];
            let u = (p.corners[1] - p.corners[0]).normalize();
            charts.push(Chart {
                u,
                v: p.normal.cross(u),
                lo: DVec2::splat(f64::INFINITY),
                hi: DVec2::splat(f64::NEG_INFINITY),
            });
            charts.len() - 1
        });
        chart_of_patch[i] = c;
    }
    let mut plane = Vec::with_capacity(mesh.vertex_count());
    let mut vertex_chart = Vec::with_capacity(mesh.vertex_count());
    for (&p, &x) in mesh.patch.iter().zip(&mesh.positions) {
        let c = *chart_of_patch.get(p as usize).ok_or_else(|| {
            Error::encode(
                "the lightmap",
                format!("a vertex names patch {p}, which the scene lacks"),
            )
        })?;
        let chart = &mut charts[c];
        let x = x.as_dvec3();
        let q = DVec2::new(x.dot(chart.u), x.dot(chart.v));
        chart.lo = chart.lo.min(q);
        chart.hi = chart.hi.max(q);
        plane.push(q);
        vertex_chart.push(c);
    }
    let used: Vec<usize> = (0..charts.len())
        .filter(|&c| charts[c].lo.x.is_finite())
        .collect();
    let area: f64 = used
        .iter()
        .map(|&c| (charts[c].hi - charts[c].lo).element_product())
        .sum();
    let largest = used
        .iter()
        .map(|&c| (charts[c].hi - charts[c].lo).max_element())
        .fold(0.0, f64::max);
    // The densest packing: shrink from a full atlas until the charts fit,
    // then bisect between the last failure and the first fit.
    let room = f64::from(resolution - 2 * PADDING - 1);
    let full = (f64::from(resolution).powi(2) / area.max(f64::MIN_POSITIVE))
        .sqrt()
        .min(room / largest.max(f64::MIN_POSITIVE));
    let mut fail = None;
    let mut density = full;
    let mut fit = None;
    for _ in 0..MAX_SHRINKS {
        if let Some(origins) = pack(&charts, &used, density, resolution) {
            fit = Some((density, origins));
            break;
        }
        fail = Some(density);
        density *= SHRINK;
    }
    let Some((mut density, mut origins)) = fit else {
        return Err(Error::Setting(format!(
            "the {} charts of the scene do not fit a {resolution}² lightmap; use a larger \
             --lightmap",
            used.len()
        )));
    };
    if let Some(mut high) = fail {
        for _ in 0..BISECTIONS {
            let middle = 0.5 * (density + high);
            match pack(&charts, &used, middle, resolution) {
                Some(o) => (density, origins) = (middle, o),
                None => high = middle,
            }
        }
    }
    let scale = 1.0 / f64::from(resolution);
    let uv = plane
        .iter()
        .zip(&vertex_chart)
        .map(|(&q, &c)| {
            let texel = origins[c] + (q - charts[c].lo) * density;
            (texel * scale).as_vec2()
        })
        .collect();
    Ok((uv, used.len(), density))
}

/// Packs the charts' rectangles at `density`; returns each chart's
/// footprint origin in texels, or `None` when they do not fit.
fn pack(charts: &[Chart], used: &[usize], density: f64, resolution: u32) -> Option<Vec<DVec2>> {
    let size = |c: usize| {
        let extent = (charts[c].hi - charts[c].lo) * density;
        (
            extent.x.ceil() as i32 + 1 + 2 * PADDING as i32,
            extent.y.ceil() as i32 + 1 + 2 * PADDING as i32,
        )
    };
    let mut order = used.to_vec();
    order.sort_by_key(|&c| {
        let (w, h) = size(c);
        (std::cmp::Reverse(h), std::cmp::Reverse(w), c)
    });
    let side = resolution as i32;
    let mut atlas = AtlasAllocator::new(size2(side, side));
    let mut origins = vec![DVec2::ZERO; charts.len()];
    for c in order {
        let (w, h) = size(c);
        let allocation = atlas.allocate(size2(w, h))?;
        let min = allocation.rectangle.min;
        // Half a texel in: the footprint starts on a texel centre's grid.
        origins[c] = DVec2::new(f64::from(min.x), f64::from(min.y)) + f64::from(PADDING) + 0.5;
    }
    Some(origins)
}

/// The atlas being written: values and, per texel, the distance (texels)
/// from the triangle that wrote it.
struct Raster {
    side: usize,
    radiosity: Frame,
    irradiance: Frame,
    distance: Vec<f64>,
}

impl Raster {
    fn new(resolution: u32) -> Raster {
        let n = (resolution as usize).pow(2);
        Raster {
            side: resolution as usize,
            radiosity: Frame::new(resolution, resolution),
            irradiance: Frame::new(resolution, resolution),
            distance: vec![f64::INFINITY; n],
        }
    }

    /// Writes every texel within [`REACH`] of the triangle's footprint
    /// that no nearer triangle wrote.
    fn triangle(&mut self, tri: [usize; 3], uv: &[Vec2], mesh: &OutputMesh) {
        let scale = self.side as f64;
        let t = tri.map(|v| uv[v].as_dvec2() * scale);
        let lo = t[0].min(t[1]).min(t[2]) - REACH;
        let hi = t[0].max(t[1]).max(t[2]) + REACH;
        let max = self.side as f64 - 1.0;
        let (x0, y0) = ((lo.x - 0.5).ceil().max(0.0), (lo.y - 0.5).ceil().max(0.0));
        let (x1, y1) = ((hi.x - 0.5).floor().min(max), (hi.y - 0.5).floor().min(max));
        if !(x0 <= x1 && y0 <= y1) {
            return;
        }
        for y in y0 as usize..=y1 as usize {
            for x in x0 as usize..=x1 as usize {
                let centre = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
                let (distance, w) = closest_on_triangle(centre, t);
                let k = y * self.side + x;
                if distance <= REACH && distance < self.distance[k] {
                    self.distance[k] = distance;
                    let mix = |values: &[Vec3]| {
                        (values[tri[0]] * w[0] as f32
                            + values[tri[1]] * w[1] as f32
                            + values[tri[2]] * w[2] as f32)
                            .max(Vec3::ZERO)
                            .to_array()
                    };
                    self.radiosity.pixels[k] = mix(&mesh.radiosity);
                    self.irradiance.pixels[k] = mix(&mesh.irradiance);
                }
            }
        }
    }

    fn covered(&self) -> usize {
        self.distance.iter().filter(|&&d| d == 0.0).count()
    }

    fn written(&self) -> usize {
        self.distance.iter().filter(|d| d.is_finite()).count()
    }
}

/// Distance from `p` to the triangle `t` (2D) and the barycentric weights
/// of its closest point (0 and `p`'s own weights when inside).
fn closest_on_triangle(p: DVec2, t: [DVec2; 3]) -> (f64, [f64; 3]) {
    let [a, b, c] = t;
    let area = (b - a).perp_dot(c - a);
    if area.abs() > 0.0 {
        let w1 = (p - a).perp_dot(c - a) / area;
        let w2 = (b - a).perp_dot(p - a) / area;
        let w0 = 1.0 - w1 - w2;
        if w0 >= 0.0 && w1 >= 0.0 && w2 >= 0.0 {
            return (0.0, [w0, w1, w2]);
        }
    }
    // Outside (or degenerate): the nearest point on the three edges.
    let mut best = (f64::INFINITY, [1.0, 0.0, 0.0]);
    for (i, j) in [(0, 1), (1, 2), (2, 0)] {
        let (p0, p1) = (t[i], t[j]);
        let d = p1 - p0;
        let s = if d.length_squared() > 0.0 {
            ((p - p0).dot(d) / d.length_squared()).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let distance = (p0 + s * d - p).length();
        if distance < best.0 {
            let mut w = [0.0; 3];
            w[i] = 1.0 - s;
            w[j] = s;
            best = (distance, w);
        }
    }
    best
}
