//! View importance [SAS92]: refinement weighed by what a view sees (and
//! what lights it) is at least as accurate in the view's pixels as plain
//! refinement, with fewer elements; the report says it was used.

use glam::DVec3;
use nusselt::hierarchical::Accuracy;
use nusselt::lab::compare::{Named, compare_frames};
use nusselt::pipeline::{SolveRun, SolveSettings, solve};
use nusselt::reference::{ReferenceSettings, render_reference};
use nusselt::render::RenderSettings;
use nusselt::render::view::{View, ViewOverrides};
use nusselt::scene::Scene;
use nusselt::util::progress::Progress;

use crate::fixtures::{LIT_ROOM, room};

/// A narrow view of one corner of the test room, its first box in front.
fn corner() -> ViewOverrides {
    ViewOverrides {
        eye: Some(DVec3::new(2.6, 1.6, 3.2)),
        target: Some(DVec3::new(0.4, 0.4, 0.6)),
        up: Some(DVec3::Y),
        fov_deg: Some(35.0),
        width: Some(48),
        height: Some(32),
    }
}

fn run(scene: &Scene, importance: bool) -> SolveRun {
    let mut settings = SolveSettings {
        importance,
        render: RenderSettings::with_samples(4, 0),
        view: corner(),
        ..SolveSettings::default()
    };
    settings.hierarchical.accuracy = Accuracy::preview();
    solve(scene, &settings, &Progress::hidden()).unwrap()
}

#[test]
fn importance_is_as_accurate_in_view_with_fewer_elements() {
    let scene = room(LIT_ROOM);
    let view = View::resolve(None, scene.bounds, &corner()).unwrap();
    let reference = render_reference(
        &scene,
        &view,
        &ReferenceSettings {
            samples_per_pixel: 1024,
            ..ReferenceSettings::default()
        },
        &Progress::hidden(),
    )
    .unwrap();
    let error = |r: &SolveRun| {
        let path = std::path::Path::new("-");
        let m = compare_frames(
            Named {
                path,
                frame: &r.frame,
            },
            Named {
                path,
                frame: &reference.image,
            },
            Some(Named {
                path,
                frame: &reference.noise,
            }),
        )
        .unwrap();
        m.overall.relative_rmse.unwrap()
    };
    let plain = run(&scene, false);
    let weighted = run(&scene, true);
    let (e_plain, e_weighted) = (error(&plain), error(&weighted));
    let (n_plain, n_weighted) = (
        plain.report.counts.elements,
        weighted.report.counts.elements,
    );
    let imp = weighted
        .report
        .importance
        .clone()
        .expect("the report says importance was used");
    eprintln!(
        "plain: {n_plain} elements, relative RMSE {e_plain:.4}; importance: {n_weighted} elements, {e_weighted:.4} ({imp:?}); reference noise {:.4}",
        reference.stats.relative_noise
    );
    assert!(plain.report.importance.is_none());
    assert!(imp.patches_seen > 0 && imp.patches_seen < imp.patches_weighted);
    assert!(imp.patches_weighted < scene.patches.len(), "{imp:?}");
    assert!(
        (n_weighted as f64) < 0.8 * n_plain as f64,
        "{n_weighted} vs {n_plain}"
    );
    assert!(
        e_weighted <= 1.1 * e_plain + reference.stats.relative_noise,
        "{e_weighted} vs {e_plain}"
    );
}
