//! The methods of the failure table, in table order.
//!
//! Owns which methods the table compares and the settings each runs at:
//! every method starts from one base (the table's seed, view, render
//! samples and sweep budget) and changes only what makes it that method,
//! so differences between rows are differences between methods.

use crate::classic::matrix::{Kernel, MatrixSettings};
use crate::classic::solve::{ClassicMethod, Convergence};
use crate::hierarchical::{Accuracy, HierarchicalSettings};
use crate::lab::failures::TableSettings;
use crate::meshing::{MeshMode, MeshSettings};
use crate::pipeline::{Method, SolveSettings};
use crate::render::RenderSettings;

/// One method of the table.
#[derive(Clone, Debug)]
pub struct TableMethod {
    /// The row's name in the table.
    pub label: &'static str,
    /// Everything the pipeline needs to run the method.
    pub settings: SolveSettings,
}

/// The methods of the table, in table order.
pub fn table_methods(t: &TableSettings) -> Vec<TableMethod> {
    let base = SolveSettings {
        matrix: MatrixSettings {
            seed: t.seed,
            ..MatrixSettings::default()
        },
        render: RenderSettings::with_samples(t.render_spp, t.seed),
        view: t.view(),
        convergence: Convergence {
            max_iterations: t.max_sweeps,
            ..Convergence::default()
        },
        ..SolveSettings::default()
    };
    let classic = |method: ClassicMethod, kernel: Kernel| {
        let mut s = SolveSettings {
            method: Method::Classic(method),
            ..base.clone()
        };
        s.matrix.kernel = kernel;
        if method == ClassicMethod::Shooting {
            s.convergence.max_iterations = t.max_shots;
        }
        s
    };
    let hierarchical = |mode: MeshMode| SolveSettings {
        method: Method::Hierarchical,
        hierarchical: HierarchicalSettings {
            accuracy: Accuracy {
                max_links: Some(t.max_links),
                ..Accuracy::default()
            },
            seed: t.seed,
            ..HierarchicalSettings::default()
        },
        mesh: MeshSettings {
            mode,
            ..MeshSettings::default()
        },
        ..base.clone()
    };
    use ClassicMethod::*;
    vec![
        TableMethod {
            label: "Gauss-Seidel, point-polygon",
            settings: classic(GaussSeidel, Kernel::PointPolygon),
        },
        TableMethod {
            label: "Gauss-Seidel, polygon-polygon",
            settings: classic(GaussSeidel, Kernel::PolygonPolygon),
        },
        TableMethod {
            label: "Gauss-Seidel, sampling",
            settings: classic(GaussSeidel, Kernel::Sampling),
        },
        TableMethod {
            label: "Gauss-Seidel, hemicube",
            settings: classic(GaussSeidel, Kernel::Hemicube),
        },
        TableMethod {
            label: "direct, point-polygon",
            settings: classic(Direct, Kernel::PointPolygon),
        },
        TableMethod {
            label: "Jacobi, point-polygon",
            settings: classic(Jacobi, Kernel::PointPolygon),
        },
        TableMethod {
            label: "shooting, point-polygon",
            settings: classic(Shooting, Kernel::PointPolygon),
        },
        TableMethod {
            label: "hierarchical, uniform mesh",
            settings: hierarchical(MeshMode::Uniform),
        },
        TableMethod {
            label: "hierarchical, quadtree mesh",
            settings: hierarchical(MeshMode::Quadtree),
        },
        TableMethod {
            label: "hierarchical, discontinuity mesh",
            settings: hierarchical(MeshMode::Discontinuity),
        },
    ]
}
