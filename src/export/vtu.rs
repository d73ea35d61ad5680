//! VTK XML unstructured grids (`.vtu`) and their time series (`.pvd`), for ParaView and
//! other VTK readers: the nodes as vertex cells, every per-node field as point data, masks as
//! integer class ids, the simulated time and the run description as field data. Binary data
//! goes in one raw appended block (`header_type="UInt64"`: each array is its byte count then
//! its bytes, little endian), the format VTK's own writers use by default.
//!
//! Written here rather than with `vtkio`: its released version writes appended data only
//! base64-encoded (raw appended data sits behind an unreleased feature), and the format needs
//! no more than an XML header with offsets; `tests/export.rs` reads the files back with an
//! independent reader (Python's `meshio`).

use std::io::{self, Write};
use std::path::Path;

/// Per-node values, as a simulation holds them (f64) or a recording stores them (f32).
#[derive(Debug, Clone, Copy)]
pub enum Values<'a> {
    F64(&'a [f64]),
    F32(&'a [f32]),
}

impl Values<'_> {
    fn len(&self) -> usize {
        match self {
            Values::F64(v) => v.len(),
            Values::F32(v) => v.len(),
        }
    }

    fn type_name(&self) -> &'static str {
        match self {
            Values::F64(_) => "Float64",
            Values::F32(_) => "Float32",
        }
    }

    /// Bytes per value.
    fn width(&self) -> usize {
        match self {
            Values::F64(_) => 8,
            Values::F32(_) => 4,
        }
    }

    fn bytes(&self) -> usize {
        self.width() * self.len()
    }

    fn write(&self, out: &mut impl Write) -> io::Result<()> {
        match self {
            Values::F64(v) => v.iter().try_for_each(|x| out.write_all(&x.to_le_bytes())),
            Values::F32(v) => v.iter().try_for_each(|x| out.write_all(&x.to_le_bytes())),
        }
    }
}

/// One frame as a VTK piece.
#[derive(Debug, Clone)]
pub struct Piece<'a> {
    /// Coordinates, `dim` per node (1 ≤ dim ≤ 3; missing ones are written as 0).
    pub dim: usize,
    pub positions: Values<'a>,
    /// (name, values): one value per node.
    pub fields: Vec<(&'a str, Values<'a>)>,
    /// (name, class ids): one id per node.
    pub classes: Vec<(&'a str, &'a [u16])>,
    /// The simulated time (field data `TimeValue`, which ParaView shows).
    pub time: f64,
    /// Texts stored as field data (UInt8 arrays of their UTF-8 bytes), e.g. the run description.
    pub texts: Vec<(&'a str, &'a str)>,
}

/// One array of the appended block: its XML element and how to write its bytes.
enum Block<'p, 'a> {
    Values(Values<'a>),
    Padded(&'p Piece<'a>),
    Classes(&'a [u16]),
    Bytes(&'a [u8]),
    Time(f64),
    Counting { n: usize, from: i64 },
    VertexTypes(usize),
}

impl Block<'_, '_> {
    fn bytes(&self) -> usize {
        match self {
            Block::Values(v) => v.bytes(),
            Block::Padded(p) => 3 * (p.positions.len() / p.dim) * p.positions.width(),
            Block::Classes(c) => 4 * c.len(),
            Block::Bytes(b) => b.len(),
            Block::Time(_) => 8,
            Block::Counting { n, .. } => 8 * n,
            Block::VertexTypes(n) => *n,
        }
    }

    fn write(&self, out: &mut impl Write) -> io::Result<()> {
        out.write_all(&(self.bytes() as u64).to_le_bytes())?;
        match self {
            Block::Values(v) => v.write(out),
            Block::Padded(p) => write_padded(p, out),
            Block::Classes(c) => c
                .iter()
                .try_for_each(|&id| out.write_all(&i32::from(id).to_le_bytes())),
            Block::Bytes(b) => out.write_all(b),
            Block::Time(t) => out.write_all(&t.to_le_bytes()),
            Block::Counting { n, from } => {
                (0..*n as i64).try_for_each(|k| out.write_all(&(k + from).to_le_bytes()))
            }
            Block::VertexTypes(n) => out.write_all(&vec![1u8; *n]),
        }
    }
}

/// Coordinates padded to 3 per node.
fn write_padded(p: &Piece, out: &mut impl Write) -> io::Result<()> {
    let dim = p.dim;
    match p.positions {
        Values::F64(v) => v.chunks_exact(dim).try_for_each(|x| {
            (0..3).try_for_each(|k| out.write_all(&x.get(k).copied().unwrap_or(0.0).to_le_bytes()))
        }),
        Values::F32(v) => v.chunks_exact(dim).try_for_each(|x| {
            (0..3).try_for_each(|k| out.write_all(&x.get(k).copied().unwrap_or(0.0).to_le_bytes()))
        }),
    }
}

/// XML-escapes an attribute value.
fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('"', "&quot;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// Writes `piece` as a `.vtu` file to `out`.
pub fn write(piece: &Piece, out: &mut impl Write) -> io::Result<()> {
    if !(1..=3).contains(&piece.dim) || !piece.positions.len().is_multiple_of(piece.dim) {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!(
                "{} coordinates do not make points of dimension {}",
                piece.positions.len(),
                piece.dim
            ),
        ));
    }
    let n = piece.positions.len() / piece.dim;
    for (name, v) in &piece.fields {
        if v.len() != n {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("field `{name}` has {} values for {n} points", v.len()),
            ));
        }
    }
    let mut blocks: Vec<Block> = Vec::new();
    let mut xml = String::new();
    let mut offset = 0usize;
    let mut array = |xml: &mut String, attributes: String, block| {
        blocks.push(block);
        let bytes = blocks.last().map_or(0, Block::bytes);
        xml.push_str(&format!(
            "<DataArray {attributes} format=\"appended\" offset=\"{offset}\"/>\n"
        ));
        offset += 8 + bytes;
    };
    xml.push_str(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" \
         byte_order=\"LittleEndian\" header_type=\"UInt64\">\n<UnstructuredGrid>\n<FieldData>\n",
    );
    array(
        &mut xml,
        "type=\"Float64\" Name=\"TimeValue\" NumberOfTuples=\"1\"".into(),
        Block::Time(piece.time),
    );
    for (name, text) in &piece.texts {
        array(
            &mut xml,
            format!(
                "type=\"UInt8\" Name=\"{}\" NumberOfTuples=\"{}\"",
                escape(name),
                text.len()
            ),
            Block::Bytes(text.as_bytes()),
        );
    }
    xml.push_str(&format!(
        "</FieldData>\n<Piece NumberOfPoints=\"{n}\" NumberOfCells=\"{n}\">\n<PointData>\n"
    ));
    for (name, values) in &piece.fields {
        array(
            &mut xml,
            format!(
                "type=\"{}\" Name=\"{}\" NumberOfComponents=\"1\"",
                values.type_name(),
                escape(name)
            ),
            Block::Values(*values),
        );
    }
    for (name, ids) in &piece.classes {
        array(
            &mut xml,
            format!(
                "type=\"Int32\" Name=\"{}\" NumberOfComponents=\"1\"",
                escape(name)
            ),
            Block::Classes(ids),
        );
    }
    xml.push_str("</PointData>\n<Points>\n");
    array(
        &mut xml,
        format!(
            "type=\"{}\" NumberOfComponents=\"3\"",
            piece.positions.type_name()
        ),
        Block::Padded(piece),
    );
    xml.push_str("</Points>\n<Cells>\n");
    array(
        &mut xml,
        "type=\"Int64\" Name=\"connectivity\"".into(),
        Block::Counting { n, from: 0 },
    );
    array(
        &mut xml,
        "type=\"Int64\" Name=\"offsets\"".into(),
        Block::Counting { n, from: 1 },
    );
    array(
        &mut xml,
        "type=\"UInt8\" Name=\"types\"".into(),
        Block::VertexTypes(n),
    );
    xml.push_str("</Cells>\n</Piece>\n</UnstructuredGrid>\n<AppendedData encoding=\"raw\">\n_");
    out.write_all(xml.as_bytes())?;
    for block in &blocks {
        block.write(out)?;
    }
    out.write_all(b"\n</AppendedData>\n</VTKFile>\n")
}

/// Writes `piece` to `path`, atomically (a temporary file renamed into place).
pub fn write_file(piece: &Piece, path: &Path) -> io::Result<()> {
    atomically(path, Durability::Renamed, |out| write(piece, out))
}

/// Writes a `.pvd` collection: (time, file name relative to the collection) per frame.
pub fn write_collection(entries: &[(f64, String)], path: &Path) -> io::Result<()> {
    atomically(path, Durability::Renamed, |out| {
        out.write_all(
            b"<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\" \
              byte_order=\"LittleEndian\">\n<Collection>\n",
        )?;
        for (time, file) in entries {
            writeln!(
                out,
                "<DataSet timestep=\"{time:e}\" group=\"\" part=\"0\" file=\"{}\"/>",
                escape(file)
            )?;
        }
        out.write_all(b"</Collection>\n</VTKFile>\n")
    })
}

/// How far a completed file is pushed before it replaces the old one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Durability {
    /// Renamed into place: no reader, and no process killed while writing, sees half a file.
    Renamed,
    /// Also on disk (fsync) before the rename: survives a machine crash too (checkpoints).
    Synced,
}

/// Writes through a buffered temporary file beside `path`, renamed into place when complete:
/// a reader (or a run cut short) never sees half a file.
pub fn atomically(
    path: &Path,
    durability: Durability,
    write: impl FnOnce(&mut io::BufWriter<std::fs::File>) -> io::Result<()>,
) -> io::Result<()> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    let temporary = path.with_file_name(format!(".{name}.partial"));
    let mut out = io::BufWriter::with_capacity(1 << 20, std::fs::File::create(&temporary)?);
    write(&mut out)?;
    let file = out.into_inner().map_err(|e| e.into_error())?;
    if durability == Durability::Synced {
        file.sync_all()?;
    }
    drop(file);
    std::fs::rename(&temporary, path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offsets_match_the_appended_blocks() {
        let positions = [0.0, 0.0, 1.0, 0.0, 0.0, 2.0];
        let damage = [0.0f32, 0.5, 1.0];
        let ids = [0u16, 1, 1];
        let piece = Piece {
            dim: 2,
            positions: Values::F64(&positions),
            fields: vec![("damage", Values::F32(&damage))],
            classes: vec![("scheme", &ids)],
            time: 1.5e-6,
            texts: vec![("run", "preset = \"x\"")],
        };
        let mut out = Vec::new();
        write(&piece, &mut out).unwrap();
        let text = String::from_utf8_lossy(&out);
        let start = text.find("\n_").unwrap() + 2;
        // Every offset points at a byte count that is followed by that many bytes, the last
        // one ending at the closing tag.
        let offsets: Vec<usize> = text
            .match_indices("offset=\"")
            .map(|(k, m)| {
                let rest = &text[k + m.len()..];
                rest[..rest.find('"').unwrap()].parse().unwrap()
            })
            .collect();
        assert_eq!(offsets.len(), 8);
        let mut end = 0;
        for &o in &offsets {
            assert_eq!(o, end, "arrays follow each other");
            let count = u64::from_le_bytes(out[start + o..start + o + 8].try_into().unwrap());
            end = o + 8 + count as usize;
        }
        assert_eq!(&out[start + end..start + end + 16], b"\n</AppendedData>");
        // The points are padded to 3D: 3 × 3 × 8 bytes.
        let points = offsets[4];
        let count = u64::from_le_bytes(out[start + points..start + points + 8].try_into().unwrap());
        assert_eq!(count, 72);
    }

    #[test]
    fn a_field_of_the_wrong_length_is_refused() {
        let piece = Piece {
            dim: 1,
            positions: Values::F64(&[0.0, 1.0]),
            fields: vec![("c", Values::F64(&[1.0]))],
            classes: Vec::new(),
            time: 0.0,
            texts: Vec::new(),
        };
        let e = write(&piece, &mut Vec::new()).unwrap_err();
        assert!(
            e.to_string()
                .contains("field `c` has 1 values for 2 points")
        );
    }
}
