//! The plain output mesh of a hierarchy: each leaf triangulated on its
//! own (quad → 2 triangles, triangle → 1), vertices welded by exact
//! position within a patch. The baseline the discontinuity mesher is
//! measured against.
//!
//! Owns: [`VertexValues`], [`output_mesh`], [`leaf_output_mesh`].
//!
//! Invariant: the vertices are the leaves' corners, each once per patch;
//! values are finite and non-negative.

use std::collections::HashMap;

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::hierarchical::HierarchicalSolution;
use crate::hierarchical::hierarchy::{ElementId, Hierarchy};
use crate::mesh::OutputMesh;
use crate::meshing::point_gather::{PointGather, PointLight, point_light};
use crate::scene::{Scene, Shape};
use crate::util::geometry::{PositionKey, position_key};
use crate::visibility::TriangleBvh;

/// How the output mesh's vertex values are made.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VertexValues {
    /// Area-weighted mean of the leaves sharing the vertex (cheap; blurs
    /// and biases next to edges, where leaves are large).
    LeafMean,
    /// [`point_light`] at the vertex, from the first leaf (in mesh
    /// order) that has it as a corner.
    PointGather {
        /// Seed of the vertices' visibility rays.
        seed: u64,
    },
}

/// The output mesh of a solved hierarchy, each vertex's radiosity made as
/// `values` says.
pub fn output_mesh(
    scene: &Scene,
    bvh: &TriangleBvh,
    solution: &HierarchicalSolution,
    values: VertexValues,
) -> OutputMesh {
    let (mut mesh, incidences) = leaf_mesh(scene, &solution.hierarchy, &solution.irradiance);
    let seed = match values {
        VertexValues::LeafMean => return mesh,
        VertexValues::PointGather { seed } => seed,
    };
    // One leaf per vertex (the first in mesh order) holds it.
    let mut holder: Vec<Option<ElementId>> = vec![None; mesh.vertex_count()];
    for &(v, leaf) in &incidences {
        holder[v as usize].get_or_insert(leaf);
    }
    let values: Vec<Option<PointLight>> = holder
        .par_iter()
        .enumerate()
        .with_min_len(16)
        .map(|(v, leaf)| {
            leaf.map(|leaf| {
                let x = mesh.positions[v].as_dvec3();
                point_light(scene, bvh, solution, leaf, x, seed, PointGather::default())
                    .non_negative()
            })
        })
        .collect();
    for (v, value) in values.into_iter().enumerate() {
        if let Some(value) = value {
            mesh.radiosity[v] = value.radiosity.as_vec3();
            mesh.irradiance[v] = value.irradiance.as_vec3();
        }
    }
    mesh
}

/// The output mesh of a solved hierarchy with leaf-mean vertex values
/// ([`VertexValues::LeafMean`]).
pub fn leaf_output_mesh(scene: &Scene, solution: &HierarchicalSolution) -> OutputMesh {
    leaf_mesh(scene, &solution.hierarchy, &solution.irradiance).0
}

/// Each leaf triangulated (quad → 2 triangles, triangle → 1), vertices
/// welded by exact position within a patch, each vertex's radiosity the
/// area-weighted mean of the leaves of its patch having it as a corner
/// (and its irradiance the same mean of `irradiance`, per element);
/// and the (vertex, leaf) incidences, in mesh order. (A discontinuity
/// mesher replaces this.)
fn leaf_mesh(
    scene: &Scene,
    hierarchy: &Hierarchy,
    irradiance: &[DVec3],
) -> (OutputMesh, Vec<(u32, ElementId)>) {
    let mut incidences = Vec::new();
    let mut mesh = OutputMesh::default();
    let mut sum: Vec<DVec3> = Vec::new();
    let mut sum_h: Vec<DVec3> = Vec::new();
    let mut weight: Vec<f64> = Vec::new();
    for patch in 0..hierarchy.root_count() {
        let normal = scene.patches[patch].normal.as_vec3();
        let mut index: HashMap<PositionKey, u32> = HashMap::new();
        let mut stack = vec![hierarchy.root(patch)];
        while let Some(id) = stack.pop() {
            let e = hierarchy.get(id);
            if let Some(kids) = e.children() {
                // Reverse so children are visited in order.
                stack.extend(kids.iter().rev());
                continue;
            }
            let corners: Vec<u32> = e
                .vertices()
                .iter()
                .map(|p| {
                    let key = position_key(*p);
                    *index.entry(key).or_insert_with(|| {
                        mesh.positions.push(p.as_vec3());
                        mesh.normals.push(normal);
                        mesh.patch.push(patch as u32);
                        sum.push(DVec3::ZERO);
                        sum_h.push(DVec3::ZERO);
                        weight.push(0.0);
                        (mesh.positions.len() - 1) as u32
                    })
                })
                .collect();
            for &k in &corners {
                sum[k as usize] += e.area * e.radiosity;
                sum_h[k as usize] += e.area * irradiance[id.index()];
                weight[k as usize] += e.area;
                incidences.push((k, id));
            }
            mesh.triangles.push([corners[0], corners[1], corners[2]]);
            if e.shape == Shape::Quad {
                mesh.triangles.push([corners[0], corners[2], corners[3]]);
            }
        }
    }
    let mean = |sum: &[DVec3]| -> Vec<Vec3> {
        sum.iter()
            .zip(&weight)
            .map(|(s, w)| {
                if *w > 0.0 {
                    (*s / *w).max(DVec3::ZERO).as_vec3()
                } else {
                    Vec3::ZERO
                }
            })
            .collect()
    };
    mesh.radiosity = mean(&sum);
    mesh.irradiance = mean(&sum_h);
    (mesh, incidences)
}
