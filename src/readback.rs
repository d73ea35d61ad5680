//! Reads a `.rrd` recording back (with the Rerun SDK's decoder): per entity, the steps logged,
//! the number of points at each step, the raw per-node values and the text documents.

use std::collections::BTreeMap;
use std::path::Path;

use rerun::log::{Chunk, LogMsg};
use rerun::{ComponentIdentifier, StoreKind, TimelineName};

/// What one entity holds.
#[derive(Debug, Default, Clone)]
pub struct EntityContent {
    /// step → number of points (2D or 3D positions) logged at that step.
    pub points: BTreeMap<i64, usize>,
    /// step → raw per-node values (the component named after the field).
    pub values: BTreeMap<i64, Vec<f32>>,
    /// step → per-node class ids (masks such as `nodes/scheme` and `nodes/phase`).
    pub classes: BTreeMap<i64, Vec<u16>>,
    /// step → scalar value.
    pub scalars: BTreeMap<i64, f64>,
    pub texts: Vec<String>,
    /// step → simulated time (s) of what was logged at that step (nanosecond resolution).
    pub times: BTreeMap<i64, f64>,
    /// step → the points' positions (only with `Positions::Keep`; 2D points get z = 0).
    pub positions: BTreeMap<i64, Vec<[f32; 3]>>,
}

/// Whether to keep the points' coordinates (an export needs them; most readers do not).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Positions {
    Count,
    Keep,
}

#[derive(Debug, Default, Clone)]
pub struct Recording {
    pub entities: BTreeMap<String, EntityContent>,
    /// Every text of the recording's blueprint (view names, entity queries, …).
    pub blueprint: Vec<String>,
}

impl Recording {
    pub fn entity(&self, path: &str) -> Option<&EntityContent> {
        self.entities.get(path)
    }
}

/// Decodes every chunk of a file, all its recordings merged. A file cut short (no footer,
/// truncated last message) still yields everything before the cut.
pub fn read(path: &Path) -> Result<Recording, String> {
    let mut merged = Recording::default();
    for (_, rec) in read_each(path)? {
        for (name, content) in rec.entities {
            let entry = merged.entities.entry(name).or_default();
            entry.points.extend(content.points);
            entry.values.extend(content.values);
            entry.classes.extend(content.classes);
            entry.scalars.extend(content.scalars);
            entry.texts.extend(content.texts);
            entry.times.extend(content.times);
            entry.positions.extend(content.positions);
        }
        merged.blueprint.extend(rec.blueprint);
    }
    Ok(merged)
}

/// The string components of a blueprint chunk, and its entity path.
fn blueprint_texts(chunk: &Chunk) -> Vec<String> {
    use rerun::external::arrow::datatypes::DataType;
    let mut texts = vec![chunk.entity_path().to_string()];
    for id in chunk.components_identifiers() {
        // The component's values (its list array's items) are strings.
        let is_text = chunk
            .raw_component_array(id)
            .is_some_and(|a| a.data_type() == &DataType::Utf8);
        if is_text {
            for slice in chunk.iter_slices::<String>(id) {
                texts.extend(slice.iter().map(|t| t.as_str().to_string()));
            }
        }
    }
    texts
}

/// Decodes every recording of a file separately, as `(recording id, content)` in the order
/// they first appear (a session that restarted holds one recording per run).
pub fn read_each(path: &Path) -> Result<Vec<(String, Recording)>, String> {
    read_each_with(path, Positions::Count)
}

/// [`read_each`], keeping the points' coordinates if asked.
pub fn read_each_with(
    path: &Path,
    positions: Positions,
) -> Result<Vec<(String, Recording)>, String> {
    let messages = crate::rrd::open(path)?;
    let step = TimelineName::from("step");
    let sim_time = TimelineName::from("sim_time");
    let pos2: ComponentIdentifier = rerun::Points2D::descriptor_positions().component;
    let pos3: ComponentIdentifier = rerun::Points3D::descriptor_positions().component;
    let text: ComponentIdentifier = rerun::TextDocument::descriptor_text().component;
    let log_text: ComponentIdentifier = rerun::TextLog::descriptor_text().component;
    let scalar: ComponentIdentifier = rerun::Scalars::descriptor_scalars().component;
    let class2: ComponentIdentifier = rerun::Points2D::descriptor_class_ids().component;
    let class3: ComponentIdentifier = rerun::Points3D::descriptor_class_ids().component;
    let mut out: Vec<(String, Recording)> = Vec::new();
    // A recording's index in `out`, added on its first message.
    let index_of = |out: &mut Vec<(String, Recording)>, id: String| match out
        .iter()
        .position(|(r, _)| *r == id)
    {
        Some(i) => i,
        None => {
            out.push((id, Recording::default()));
            out.len() - 1
        }
    };
    for msg in messages {
        let msg = msg?;
        let (store, arrow) = match &msg {
            LogMsg::SetStoreInfo(info) if info.info.store_id.kind() == StoreKind::Recording => {
                index_of(&mut out, info.info.store_id.recording_id().to_string());
                continue;
            }
            LogMsg::ArrowMsg(store, arrow) => (store, arrow),
            _ => continue,
        };
        let chunk = Chunk::from_arrow_msg(arrow).map_err(|e| format!("{}: {e}", path.display()))?;
        if store.kind() == StoreKind::Blueprint {
            // A recording's default blueprint follows its store info: it belongs to the
            // recording announced last.
            if let Some((_, last)) = out.last_mut() {
                last.blueprint.extend(blueprint_texts(&chunk));
            }
            continue;
        }
        let index = index_of(&mut out, store.recording_id().to_string());
        let name = chunk.entity_path().to_string();
        let entry = out[index].1.entities.entry(name.clone()).or_default();
        let field = name.rsplit('/').next().unwrap_or_default().to_string();
        let field_id = ComponentIdentifier::try_new(field.as_str()).ok();
        if let (Some(steps), Some(times)) = (
            chunk.timelines().get(&step),
            chunk.timelines().get(&sim_time),
        ) {
            for (&n, &t) in steps.times_raw().iter().zip(times.times_raw()) {
                entry.times.insert(n, t as f64 * 1e-9);
            }
        }
        let keep = positions == Positions::Keep;
        for id in chunk.components_identifiers() {
            if id == pos2 {
                for ((t, _), p) in chunk
                    .iter_component_indices(step, id)
                    .zip(chunk.iter_slices::<[f32; 2]>(id))
                {
                    entry.points.insert(t.as_i64(), p.len());
                    if keep {
                        let xyz = p.iter().map(|q| [q[0], q[1], 0.0]).collect();
                        entry.positions.insert(t.as_i64(), xyz);
                    }
                }
            } else if id == pos3 {
                for ((t, _), p) in chunk
                    .iter_component_indices(step, id)
                    .zip(chunk.iter_slices::<[f32; 3]>(id))
                {
                    entry.points.insert(t.as_i64(), p.len());
                    if keep {
                        entry.positions.insert(t.as_i64(), p.to_vec());
                    }
                }
            } else if id == class2 || id == class3 {
                for ((t, _), c) in chunk
                    .iter_component_indices(step, id)
                    .zip(chunk.iter_slices::<u16>(id))
                {
                    entry.classes.insert(t.as_i64(), c.to_vec());
                }
            } else if id == text || id == log_text {
                for texts in chunk.iter_slices::<String>(id) {
                    entry
                        .texts
                        .extend(texts.iter().map(|t| t.as_str().to_string()));
                }
            } else if id == scalar {
                for ((t, _), v) in chunk
                    .iter_component_indices(step, id)
                    .zip(chunk.iter_slices::<f64>(id))
                {
                    if let Some(v) = v.first() {
                        entry.scalars.insert(t.as_i64(), *v);
                    }
                }
            } else if Some(id) == field_id {
                for ((t, _), v) in chunk
                    .iter_component_indices(step, id)
                    .zip(chunk.iter_slices::<f32>(id))
                {
                    entry.values.insert(t.as_i64(), v.to_vec());
                }
            }
        }
    }
    Ok(out)
}
