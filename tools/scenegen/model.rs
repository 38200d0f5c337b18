//! The generator's own description of a scene, before it becomes glTF.
//!
//! Geometry is kept in `f64` metres and only rounded to the micrometre (then
//! to `f32`) by the encoder, so that trigonometry-built shapes give the same
//! bytes on every run. Every triangle is listed counter-clockwise seen from
//! its front (lit) side, as glTF requires. Punctual lights
//! (`KHR_lights_punctual`) live in the scene's light list and are placed by
//! the nodes that name them; spot and directional lights shine down their
//! node's local −z.

use glam::{DAffine3, DQuat, DVec3};

/// A diffuse material: reflectance ρ and, for emitters, the emitted radiance.
#[derive(Clone, Debug)]
pub struct Material {
    pub name: &'static str,
    /// ρ, written as `baseColorFactor.rgb`; every component below 1.
    pub reflectance: [f64; 3],
    pub emission: Option<Emission>,
    /// Where the numbers come from, for the README.
    pub note: &'static str,
}

/// Emitted radiance L_e = `factor` × `strength`.
#[derive(Clone, Copy, Debug)]
pub struct Emission {
    /// `emissiveFactor`, every component in [0, 1].
    pub factor: [f64; 3],
    /// `KHR_materials_emissive_strength.emissiveStrength`; `None` writes no
    /// extension (a strength of 1).
    pub strength: Option<f64>,
}

impl Emission {
    /// L_e in W·m⁻²·sr⁻¹ per channel.
    pub fn radiance(&self) -> [f64; 3] {
        let s = self.strength.unwrap_or(1.0);
        self.factor.map(|c| c * s)
    }

    /// Emission of radiance `l` split into a factor whose largest component
    /// is 1 and a strength carrying the magnitude.
    pub fn with_strength(l: [f64; 3]) -> Emission {
        let peak = l.iter().copied().fold(0.0, f64::max);
        Emission {
            factor: l.map(|c| c / peak),
            strength: Some(peak),
        }
    }
}

/// A named triangle list with one material.
#[derive(Clone, Debug)]
pub struct Mesh {
    pub name: String,
    pub material: usize,
    pub triangles: Vec<[DVec3; 3]>,
}

/// A perspective camera; it looks down its node's local −z with +y up.
#[derive(Clone, Copy, Debug)]
pub struct Camera {
    /// Vertical field of view in radians.
    pub yfov: f64,
    pub aspect_ratio: f64,
    pub znear: f64,
}

/// The kind of a `KHR_lights_punctual` light, with its cone for spots.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightKind {
    /// Shines equally in every direction from its node's position; the
    /// node's rotation is ignored.
    Point,
    /// Shines down its node's local −z: at full intensity within
    /// `inner_cone_angle` of that axis, falling to nothing at
    /// `outer_cone_angle` (radians, 0 ≤ inner < outer ≤ π/2).
    Spot {
        inner_cone_angle: f64,
        outer_cone_angle: f64,
    },
    /// Parallel light down its node's local −z, from infinitely far away;
    /// the node's position is ignored.
    Directional,
}

impl LightKind {
    /// The glTF `type` string.
    pub fn name(self) -> &'static str {
        match self {
            LightKind::Point => "point",
            LightKind::Spot { .. } => "spot",
            LightKind::Directional => "directional",
        }
    }
}

/// A `KHR_lights_punctual` light, placed by the node(s) that name it.
#[derive(Clone, Debug)]
pub struct Light {
    pub name: &'static str,
    pub kind: LightKind,
    /// Linear RGB `color`, every component in [0, 1].
    pub color: [f64; 3],
    /// `intensity`: read as W·sr⁻¹ for point and spot lights and as W·m⁻²
    /// for directional ones (the glTF spec's candela and lux), so that a
    /// surface facing the light gets irradiance `color` × I / r² or
    /// `color` × E.
    pub intensity: f64,
}

/// A named node: a mesh, a camera, or a group of children.
#[derive(Clone, Debug, Default)]
pub struct Node {
    pub name: String,
    pub mesh: Option<usize>,
    pub camera: Option<Camera>,
    /// Index into [`SceneDef::lights`] of the light this node places.
    pub light: Option<usize>,
    pub translation: Option<DVec3>,
    pub rotation: Option<DQuat>,
    /// Scale along the node's local axes (applied first, as glTF does).
    pub scale: Option<DVec3>,
    pub children: Vec<usize>,
}

/// How the geometry buffer is stored next to the JSON.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BufferStorage {
    /// `<stem>.bin` beside the `.gltf`.
    External,
    /// A base64 `data:` URI inside the `.gltf`.
    Embedded,
}

/// One bundled scene.
#[derive(Clone, Debug)]
pub struct SceneDef {
    /// File name without `.gltf`.
    pub stem: String,
    pub title: String,
    /// Markdown prose for the README: what the scene shows and why.
    pub about: String,
    pub storage: BufferStorage,
    pub materials: Vec<Material>,
    pub meshes: Vec<Mesh>,
    pub nodes: Vec<Node>,
    /// `KHR_lights_punctual` lights; every one is placed by some node.
    pub lights: Vec<Light>,
    /// Nodes of the glTF scene's root list, in order.
    pub roots: Vec<usize>,
}

impl SceneDef {
    pub fn new(stem: &str, title: &str, storage: BufferStorage) -> SceneDef {
        SceneDef {
            stem: stem.to_owned(),
            title: title.to_owned(),
            about: String::new(),
            storage,
            materials: Vec::new(),
            meshes: Vec::new(),
            nodes: Vec::new(),
            lights: Vec::new(),
            roots: Vec::new(),
        }
    }

    pub fn add_material(&mut self, material: Material) -> usize {
        self.materials.push(material);
        self.materials.len() - 1
    }

    /// A non-emitting material of reflectance `rho`.
    pub fn add_diffuse(&mut self, name: &'static str, rho: [f64; 3], note: &'static str) -> usize {
        self.add_material(Material {
            name,
            reflectance: rho,
            emission: None,
            note,
        })
    }

    pub fn add_mesh(&mut self, name: &str, material: usize, triangles: Vec<[DVec3; 3]>) -> usize {
        self.meshes.push(Mesh {
            name: name.to_owned(),
            material,
            triangles,
        });
        self.meshes.len() - 1
    }

    /// Adds a node (not yet attached to any parent) and returns its index.
    pub fn add_node(&mut self, node: Node) -> usize {
        self.nodes.push(node);
        self.nodes.len() - 1
    }

    /// A root node holding a new mesh of the same name, placed at the origin.
    pub fn add_surface(&mut self, name: &str, material: usize, triangles: Vec<[DVec3; 3]>) {
        let mesh = self.add_mesh(name, material, triangles);
        let node = self.add_node(Node {
            name: name.to_owned(),
            mesh: Some(mesh),
            ..Node::default()
        });
        self.roots.push(node);
    }

    /// A root camera node at `eye` looking at `target` with `up` roughly up.
    pub fn add_camera(&mut self, name: &str, eye: DVec3, target: DVec3, up: DVec3, camera: Camera) {
        let node = self.add_node(Node {
            name: name.to_owned(),
            camera: Some(camera),
            translation: Some(eye),
            rotation: Some(look_rotation(target - eye, up)),
            ..Node::default()
        });
        self.roots.push(node);
    }

    /// A root node of the light's name placing `light` at `position`; spot
    /// and directional lights get the rotation that turns their local −z
    /// along `direction` (+y kept as up as far as possible), point lights
    /// no rotation.
    pub fn add_light(&mut self, light: Light, position: DVec3, direction: DVec3) {
        let rotation = (light.kind != LightKind::Point).then(|| {
            let up = if direction.normalize().y.abs() > 0.99 {
                DVec3::NEG_Z
            } else {
                DVec3::Y
            };
            look_rotation(direction, up)
        });
        let name = light.name.to_owned();
        self.lights.push(light);
        let node = self.add_node(Node {
            name,
            light: Some(self.lights.len() - 1),
            translation: Some(position),
            rotation,
            ..Node::default()
        });
        self.roots.push(node);
    }
}

/// The rotation taking the camera frame (looking down −z, +y up) to one
/// looking along `forward` with `up` as close to up as possible.
pub fn look_rotation(forward: DVec3, up: DVec3) -> DQuat {
    let back = -forward.normalize();
    let right = up.cross(back).normalize();
    let true_up = back.cross(right);
    DQuat::from_mat3(&glam::DMat3::from_cols(right, true_up, back)).normalize()
}

/// World transform of every node reachable from the roots (None otherwise).
pub fn world_transforms(scene: &SceneDef) -> Vec<Option<DAffine3>> {
    let mut out = vec![None; scene.nodes.len()];
    let mut stack: Vec<(usize, DAffine3)> = scene
        .roots
        .iter()
        .rev()
        .map(|&r| (r, DAffine3::IDENTITY))
        .collect();
    while let Some((n, parent)) = stack.pop() {
        let node = &scene.nodes[n];
        let local = DAffine3::from_scale_rotation_translation(
            node.scale.unwrap_or(DVec3::ONE),
            node.rotation.unwrap_or_default(),
            node.translation.unwrap_or_default(),
        );
        let world = parent * local;
        out[n] = Some(world);
        stack.extend(node.children.iter().rev().map(|&c| (c, world)));
    }
    out
}

/// Total triangle count of the nodes reachable from the roots.
pub fn triangle_count(s: &SceneDef) -> usize {
    let world = world_transforms(s);
    s.nodes
        .iter()
        .enumerate()
        .filter(|(n, _)| world[*n].is_some())
        .filter_map(|(_, node)| node.mesh)
        .map(|m| s.meshes[m].triangles.len())
        .sum()
}
