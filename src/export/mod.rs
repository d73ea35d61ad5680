//! Export for ParaView and other VTK readers: one `.vtu` per frame and a `.pvd` time series,
//! written while running (`VtuSeries`, on its own thread, fed the frames the recording gets)
//! or from a saved recording (`from_recording`).

pub mod vtu;

use std::path::{Path, PathBuf};
use std::thread::JoinHandle;

use crossbeam_channel::{Sender, bounded};

use crate::frame::Frame;
use crate::readback::{self, Positions};
use vtu::{Piece, Values};

/// Frames in flight to the writing thread (the solver waits when it falls behind).
const CHANNEL_CAPACITY: usize = 4;

/// A frame's piece: positions, fields and masks as the simulation holds them.
fn piece_of<'a>(frame: &'a Frame, run: &'a str) -> Piece<'a> {
    Piece {
        dim: frame.dim,
        positions: Values::F64(&frame.positions),
        fields: frame
            .fields
            .iter()
            .map(|f| (f.name.as_ref(), Values::F64(&f.values)))
            .collect(),
        classes: frame
            .classes
            .iter()
            .map(|c| (c.name, c.ids.as_slice()))
            .collect(),
        time: frame.time,
        texts: vec![("run", run)],
    }
}

/// A time series being written: the frames so far and the collection listing them.
struct Series {
    dir: PathBuf,
    prefix: String,
    entries: Vec<(f64, String)>,
}

impl Series {
    fn new(dir: &Path, prefix: &str) -> Result<Series, String> {
        std::fs::create_dir_all(dir)
            .map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
        Ok(Series {
            dir: dir.to_path_buf(),
            prefix: prefix.to_string(),
            entries: Vec::new(),
        })
    }

    /// Writes one frame's file, then the collection (so a series cut short stays readable).
    fn add(&mut self, step: i64, piece: &Piece) -> Result<(), String> {
        let file = format!("{}_{step:08}.vtu", self.prefix);
        let path = self.dir.join(&file);
        vtu::write_file(piece, &path)
            .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
        self.entries.push((piece.time, file));
        let pvd = self.collection();
        vtu::write_collection(&self.entries, &pvd)
            .map_err(|e| format!("cannot write {}: {e}", pvd.display()))
    }

    fn collection(&self) -> PathBuf {
        self.dir.join(format!("{}.pvd", self.prefix))
    }
}

/// A `.vtu` series written while running, off the solver thread.
pub struct VtuSeries {
    sender: Option<Sender<Frame>>,
    worker: Option<JoinHandle<Result<usize, String>>>,
}

impl VtuSeries {
    /// Starts writing `DIR/PREFIX_STEP.vtu` and `DIR/PREFIX.pvd`; `run` (the run
    /// description) goes into every file as field data.
    pub fn start(dir: &Path, prefix: &str, run: String) -> Result<VtuSeries, String> {
        let mut series = Series::new(dir, prefix)?;
        let (sender, receiver) = bounded::<Frame>(CHANNEL_CAPACITY);
        let worker = std::thread::Builder::new()
            .name("vtu-writer".into())
            .spawn(move || {
                for frame in receiver {
                    series.add(frame.step as i64, &piece_of(&frame, &run))?;
                }
                Ok(series.entries.len())
            })
            .map_err(|e| format!("cannot start the VTU writer: {e}"))?;
        Ok(VtuSeries {
            sender: Some(sender),
            worker: Some(worker),
        })
    }

    pub fn send(&mut self, frame: Frame) {
        if let Some(s) = &self.sender {
            let _ = s.send(frame);
        }
    }

    /// Writes what is queued; returns the number of files written.
    pub fn finish(mut self) -> Result<usize, String> {
        drop(self.sender.take());
        match self.worker.take() {
            Some(w) => w
                .join()
                .map_err(|_| "the VTU writer panicked".to_string())?,
            None => Ok(0),
        }
    }
}

impl Drop for VtuSeries {
    fn drop(&mut self) {
        drop(self.sender.take());
        if let Some(w) = self.worker.take() {
            let _ = w.join();
        }
    }
}

/// What an export wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct Exported {
    pub frames: usize,
    pub collection: PathBuf,
    /// Point counts, frame by frame.
    pub points: Vec<usize>,
}

/// Writes recording `index` (0 = the first) of a `.rrd` file as a `.vtu` series in `dir`:
/// every `nodes/<field>` entity's values and every mask's class ids as point data, at the
/// logged positions, the simulated time and the run description as field data.
pub fn from_recording(path: &Path, index: usize, dir: &Path) -> Result<Exported, String> {
    let recordings = readback::read_each_with(path, Positions::Keep)?;
    let count = recordings.len();
    let (id, rec) = recordings.into_iter().nth(index).ok_or_else(|| {
        format!(
            "{}: --recording {index} is out of range (the file holds {count} recording{}: 0..{})",
            path.display(),
            if count == 1 { "" } else { "s" },
            count.saturating_sub(1)
        )
    })?;
    let run = rec
        .entity("/control/run")
        .and_then(|e| e.texts.last().cloned())
        .unwrap_or_default();
    let nodes: Vec<(&str, &readback::EntityContent)> = rec
        .entities
        .iter()
        .filter_map(|(name, e)| Some((name.strip_prefix("/nodes/")?, e)))
        .collect();
    let steps: std::collections::BTreeSet<i64> = nodes
        .iter()
        .flat_map(|(_, e)| e.positions.keys().copied())
        .collect();
    if steps.is_empty() {
        return Err(format!(
            "{}: recording {index} ({id}) holds no node frames",
            path.display()
        ));
    }
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_else(|| "frames".into());
    let mut series = Series::new(dir, &format!("{stem}_rec{index}"))?;
    let mut points = Vec::new();
    for step in steps {
        let Some((_, with_positions)) = nodes.iter().find(|(_, e)| e.positions.contains_key(&step))
        else {
            continue;
        };
        let positions = with_positions.positions[&step].as_flattened();
        let n = positions.len() / 3;
        let fields: Vec<(&str, Values)> = nodes
            .iter()
            .filter_map(|(name, e)| {
                let v = e.values.get(&step)?;
                (v.len() == n).then_some((*name, Values::F32(v)))
            })
            .collect();
        let classes: Vec<(&str, &[u16])> = nodes
            .iter()
            .filter_map(|(name, e)| {
                let c = e.classes.get(&step)?;
                (c.len() == n).then_some((*name, c.as_slice()))
            })
            .collect();
        let piece = Piece {
            dim: 3,
            positions: Values::F32(positions),
            fields,
            classes,
            time: with_positions.times.get(&step).copied().unwrap_or(0.0),
            texts: vec![("run", &run)],
        };
        series.add(step, &piece)?;
        points.push(n);
    }
    Ok(Exported {
        frames: points.len(),
        collection: series.collection(),
        points,
    })
}
