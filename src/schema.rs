//! JSON Schemas of the JSON files nusselt writes, generated from the types
//! that serialise them (`schemars`, draft 2020-12).
//!
//! Owns: the list of files and their schemas. The repository keeps a copy
//! of each under `src/schemas/`; a test regenerates them and fails when the
//! committed copy differs, so the files always describe what the program
//! writes.

use schemars::{JsonSchema, Schema, schema_for};

use crate::lab::compare::Metrics;
use crate::lab::points::PointScore;
use crate::reference::ReferenceStats;
use crate::report::Report;

/// Each schema's file name under `src/schemas/` and its text (pretty JSON
/// with a final newline), in a fixed order:
/// - `report.schema.json`: `report.json` of `nusselt solve`;
/// - `metrics.schema.json`: `metrics.json` of `nusselt compare` on images;
/// - `point-metrics.schema.json`: `metrics.json` of `nusselt compare`
///   against a point table;
/// - `reference.schema.json`: the `.json` beside a `nusselt reference` image.
pub fn schemas() -> Vec<(&'static str, String)> {
    vec![
        ("report.schema.json", text::<Report>()),
        ("metrics.schema.json", text::<Metrics>()),
        ("point-metrics.schema.json", text::<PointScore>()),
        ("reference.schema.json", text::<ReferenceStats>()),
    ]
}

/// The schema of `T` as the committed files hold it.
fn text<T: JsonSchema>() -> String {
    let schema: Schema = schema_for!(T);
    let mut text = serde_json::to_string_pretty(&schema).unwrap_or_default();
    text.push('\n');
    text
}
