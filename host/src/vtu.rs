//! VTK XML unstructured grids (`.vtu`, ASCII) of tetrahedral meshes, and `.pvd` collections that
//! string them into a time series, for viewing in ParaView; and [`read_vtu`], which reads the
//! tetrahedra of a `.vtu` file (SOFA's fine liver) through the `vtkio` crate.
//!
//! ASCII rather than binary so that the files can be read and diffed; numbers are written in the
//! shortest decimal form that reads back to the same `f64`, so the same input always gives the
//! same bytes. Every input is checked before the file is created: on an `InvalidInput` error
//! nothing is written.

use std::collections::HashSet;
use std::fmt::Display;
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::Path;

use vtkio::model::{CellType, DataSet, VertexNumbers};

use crate::msh::RoundTrip;

/// VTK's cell type number of the linear tetrahedron (`VTK_TETRA`).
const VTK_TETRA: u8 = 10;

/// Largest `.vtu` file [`read_vtu`] reads, bytes (256 MiB: a mesh of millions of elements).
pub const MAX_VTU_BYTES: u64 = 256 << 20;

/// How many scalars, offsets or types go on one line of a data array.
const PER_ROW: usize = 8;

/// Writes a tetrahedral mesh with optional data as a VTK XML unstructured grid (`.vtu`, ASCII).
///
/// - `points`: positions, in the caller's length unit (ParaView shows them as they are).
/// - `tets`: 0-based indices into `points`, written as `VTK_TETRA` cells in the given node order.
/// - `point_vectors`: named 3-vectors per point (displacement, velocity, …), each of length
///   `points.len()`; the first is marked as the active vectors.
/// - `cell_scalars`: named scalars per tetrahedron (strain energy, volume ratio, …), each of
///   length `tets.len()`; the first is marked as the active scalars.
///
/// # Errors
/// `InvalidInput`, before anything is written, if a data array's length does not match, a
/// tetrahedron refers to a point index `>= points.len()`, a value is NaN or infinite (VTK's
/// ASCII reader cannot read those), or an array name is empty, holds a control character or is
/// used twice in the same group; otherwise the I/O errors of creating and writing `path`.
pub fn write_vtu(
    path: &Path,
    points: &[[f64; 3]],
    tets: &[[u32; 4]],
    point_vectors: &[(&str, &[[f64; 3]])],
    cell_scalars: &[(&str, &[f64])],
) -> io::Result<()> {
    check_vtu_input(points, tets, point_vectors, cell_scalars)?;
    let mut w = BufWriter::new(File::create(path)?);
    writeln!(w, r#"<?xml version="1.0"?>"#)?;
    writeln!(
        w,
        r#"<VTKFile type="UnstructuredGrid" version="0.1" byte_order="LittleEndian">"#
    )?;
    writeln!(w, "  <UnstructuredGrid>")?;
    writeln!(
        w,
        r#"    <Piece NumberOfPoints="{}" NumberOfCells="{}">"#,
        points.len(),
        tets.len()
    )?;
    if let Some((active, _)) = point_vectors.first() {
        writeln!(w, r#"      <PointData Vectors="{}">"#, escape(active))?;
        for (name, values) in point_vectors {
            write_array(
                &mut w,
                "Float64",
                Some(name),
                3,
                values.iter().map(|v| v.map(RoundTrip)),
            )?;
        }
        writeln!(w, "      </PointData>")?;
    }
    if let Some((active, _)) = cell_scalars.first() {
        writeln!(w, r#"      <CellData Scalars="{}">"#, escape(active))?;
        for (name, values) in cell_scalars {
            write_array(
                &mut w,
                "Float64",
                Some(name),
                1,
                rows(values.iter().map(|&v| RoundTrip(v))),
            )?;
        }
        writeln!(w, "      </CellData>")?;
    }
    writeln!(w, "      <Points>")?;
    write_array(
        &mut w,
        "Float64",
        None,
        3,
        points.iter().map(|p| p.map(RoundTrip)),
    )?;
    writeln!(w, "      </Points>")?;
    writeln!(w, "      <Cells>")?;
    write_array(
        &mut w,
        "Int64",
        Some("connectivity"),
        1,
        tets.iter().copied(),
    )?;
    write_array(
        &mut w,
        "Int64",
        Some("offsets"),
        1,
        rows((1..=tets.len()).map(|k| 4 * k)),
    )?;
    write_array(
        &mut w,
        "UInt8",
        Some("types"),
        1,
        rows(tets.iter().map(|_| VTK_TETRA)),
    )?;
    writeln!(w, "      </Cells>")?;
    writeln!(w, "    </Piece>")?;
    writeln!(w, "  </UnstructuredGrid>")?;
    writeln!(w, "</VTKFile>")?;
    w.flush()
}

/// Writes a ParaView collection (`.pvd`) that plays `.vtu` files as a time series.
///
/// `steps` holds `(time, file)` pairs in the order to list them: `time` in the caller's unit
/// (seconds, or frame numbers), `file` relative to the directory of `path` (ParaView resolves it
/// from there), e.g. `"frames/step_0003.vtu"`.
///
/// # Errors
/// `InvalidInput`, before anything is written, if a time is NaN or infinite or a file name is
/// empty or holds a control character; otherwise the I/O errors of creating and writing `path`.
pub fn write_pvd(path: &Path, steps: &[(f64, String)]) -> io::Result<()> {
    for (k, (time, file)) in steps.iter().enumerate() {
        if !time.is_finite() {
            return Err(invalid(format!("step {k}: the time {time} is not finite")));
        }
        check_text(file, &format!("step {k}: the file name"))?;
    }
    let mut w = BufWriter::new(File::create(path)?);
    writeln!(w, r#"<?xml version="1.0"?>"#)?;
    writeln!(
        w,
        r#"<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">"#
    )?;
    writeln!(w, "  <Collection>")?;
    for (time, file) in steps {
        writeln!(
            w,
            r#"    <DataSet timestep="{}" group="" part="0" file="{}"/>"#,
            RoundTrip(*time),
            escape(file)
        )?;
    }
    writeln!(w, "  </Collection>")?;
    writeln!(w, "</VTKFile>")?;
    w.flush()
}

/// The tetrahedra of a VTK XML unstructured grid, as read by [`read_vtu`].
///
/// What [`read_vtu`] promises on return: every coordinate is finite, `tets` is not empty and
/// every index in it is below `nodes.len()`.
#[derive(Clone, Debug, PartialEq)]
pub struct VtuMesh {
    /// Point positions in the file's length unit (nothing is converted), in file order, the
    /// points of all pieces one after the other.
    pub nodes: Vec<[f64; 3]>,
    /// The `VTK_TETRA` cells as 0-based indices into `nodes`, with the file's node order.
    pub tets: Vec<[u32; 4]>,
    /// How many cells of other types were dropped.
    pub skipped_cells: usize,
}

/// Why a `.vtu` file could not be read: the file and what is wrong.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct VtuError {
    /// The file, as given to [`read_vtu`].
    pub file: String,
    /// What is wrong.
    pub message: String,
}

impl Display for VtuError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.file, self.message)
    }
}

impl std::error::Error for VtuError {}

/// Reads the tetrahedra (`VTK_TETRA`, type 10) of the VTK XML unstructured grid at `path`:
/// ASCII, raw binary or base64 data, zlib-compressed or not, either byte order, one piece or
/// several (their points are numbered one after the other). Other cell types are counted and
/// dropped.
///
/// Parsing is `vtkio`'s, the VTK file reader of the Rust ecosystem; this function only checks
/// what a simulation needs.
///
/// # Errors
/// A [`VtuError`] naming `path`: a file that cannot be read or parsed, that is not an
/// unstructured grid, points that are not 3-vectors of numbers or not finite, a tetrahedron
/// that does not have four points or names a point that does not exist, or no tetrahedron at
/// all.
pub fn read_vtu(path: &Path) -> Result<VtuMesh, VtuError> {
    let file = path.display().to_string();
    let fail = |message: String| VtuError {
        file: file.clone(),
        message,
    };
    // Checked before vtkio reads the file whole (SOFA's fine liver is 1 MB).
    let bytes = std::fs::metadata(path)
        .map_err(|e| fail(format!("cannot read: {e}")))?
        .len();
    if bytes > MAX_VTU_BYTES {
        return Err(fail(format!(
            "{bytes} bytes; a model mesh file is at most {MAX_VTU_BYTES} bytes"
        )));
    }
    // vtkio panics on some damaged files (an `unwrap` in its XML reader, found by
    // `tests/fuzz_readers.rs`): a panic there is an unreadable file, not a crash. The programs
    // install [`quiet_reader_panics`], so that it prints nothing but the error below.
    let vtk = std::panic::catch_unwind(|| vtkio::Vtk::import(path))
        .map_err(|_| fail("cannot read: the VTK reader failed on the file's XML".into()))?
        .map_err(|e| fail(format!("cannot read: {e}")))?;
    let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else {
        return Err(fail(
            "not an unstructured grid (VTK_UNSTRUCTURED_GRID)".into(),
        ));
    };
    let mut out = VtuMesh {
        nodes: vec![],
        tets: vec![],
        skipped_cells: 0,
    };
    for (k, piece) in pieces.into_iter().enumerate() {
        let piece = piece
            .into_loaded_piece_data(vtk.file_path.as_deref())
            .map_err(|e| fail(format!("piece {k}: {e}")))?;
        let first = out.nodes.len();
        let coords: Vec<f64> = piece
            .points
            .cast_into()
            .ok_or_else(|| fail(format!("piece {k}: the points are not numbers")))?;
        if !coords.len().is_multiple_of(3) {
            return Err(fail(format!(
                "piece {k}: {} point coordinates, not a multiple of 3",
                coords.len()
            )));
        }
        for (i, p) in coords.chunks_exact(3).enumerate() {
            if p.iter().any(|c| !c.is_finite()) {
                return Err(fail(format!("piece {k}: point {i} is not finite: {p:?}")));
            }
            out.nodes.push([p[0], p[1], p[2]]);
        }
        let count = out.nodes.len() - first;
        let (connectivity, offsets) = match piece.cells.cell_verts {
            VertexNumbers::XML {
                connectivity,
                offsets,
            } => (connectivity, offsets),
            legacy @ VertexNumbers::Legacy { .. } => legacy.into_xml(),
        };
        if offsets.len() != piece.cells.types.len() {
            return Err(fail(format!(
                "piece {k}: {} cell offsets but {} cell types",
                offsets.len(),
                piece.cells.types.len()
            )));
        }
        let mut start = 0usize;
        for (c, (&end, ty)) in offsets.iter().zip(&piece.cells.types).enumerate() {
            let end = usize::try_from(end).unwrap_or(usize::MAX);
            let verts = connectivity.get(start..end).ok_or_else(|| {
                fail(format!(
                    "piece {k}: cell {c} ends at {end}, outside the {} connectivity entries",
                    connectivity.len()
                ))
            })?;
            start = end;
            if *ty != CellType::Tetra {
                out.skipped_cells += 1;
                continue;
            }
            if verts.len() != 4 {
                return Err(fail(format!(
                    "piece {k}: tetrahedron {c} has {} points",
                    verts.len()
                )));
            }
            let mut tet = [0u32; 4];
            for (slot, &v) in tet.iter_mut().zip(verts) {
                let v = usize::try_from(v).unwrap_or(usize::MAX);
                if v >= count {
                    return Err(fail(format!(
                        "piece {k}: tetrahedron {c} names point {v}, but there are {count}"
                    )));
                }
                *slot = u32::try_from(first + v)
                    .map_err(|_| fail(format!("piece {k}: more than 2^32 points")))?;
            }
            out.tets.push(tet);
        }
    }
    if out.tets.is_empty() {
        return Err(fail("no tetrahedron (VTK_TETRA) in the file".into()));
    }
    Ok(out)
}

fn invalid(message: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidInput, message)
}

/// Everything [`write_vtu`] refuses, checked before the file is created.
fn check_vtu_input(
    points: &[[f64; 3]],
    tets: &[[u32; 4]],
    point_vectors: &[(&str, &[[f64; 3]])],
    cell_scalars: &[(&str, &[f64])],
) -> io::Result<()> {
    if let Some(i) = points.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        return Err(invalid(format!(
            "point {i} has a coordinate that is not finite"
        )));
    }
    for (k, tet) in tets.iter().enumerate() {
        if let Some(&v) = tet.iter().find(|&&v| v as usize >= points.len()) {
            return Err(invalid(format!(
                "tetrahedron {k} refers to point {v}, but there are {} points",
                points.len()
            )));
        }
    }
    let mut names = HashSet::new();
    for (name, values) in point_vectors {
        check_name(name, "point", &mut names)?;
        if values.len() != points.len() {
            return Err(invalid(format!(
                "point vectors {name:?} hold {} values for {} points",
                values.len(),
                points.len()
            )));
        }
        if let Some(i) = values.iter().position(|v| !v.iter().all(|c| c.is_finite())) {
            return Err(invalid(format!(
                "point vectors {name:?}: value {i} is not finite"
            )));
        }
    }
    names.clear();
    for (name, values) in cell_scalars {
        check_name(name, "cell", &mut names)?;
        if values.len() != tets.len() {
            return Err(invalid(format!(
                "cell scalars {name:?} hold {} values for {} tetrahedra",
                values.len(),
                tets.len()
            )));
        }
        if let Some(i) = values.iter().position(|v| !v.is_finite()) {
            return Err(invalid(format!(
                "cell scalars {name:?}: value {i} is not finite"
            )));
        }
    }
    Ok(())
}

/// An array name must be valid XML text and unique within its group, or ParaView would show
/// one array under two entries or not at all.
fn check_name<'a>(name: &'a str, group: &str, seen: &mut HashSet<&'a str>) -> io::Result<()> {
    check_text(name, &format!("a {group} data name"))?;
    if !seen.insert(name) {
        return Err(invalid(format!(
            "the {group} data name {name:?} is used twice"
        )));
    }
    Ok(())
}

/// Text for an XML attribute: not empty, no control characters (XML 1.0 cannot hold most of
/// them even escaped).
fn check_text(text: &str, what: &str) -> io::Result<()> {
    if text.is_empty() {
        return Err(invalid(format!("{what} is empty")));
    }
    if text.chars().any(char::is_control) {
        return Err(invalid(format!(
            "{what} {text:?} holds a control character"
        )));
    }
    Ok(())
}

/// `text` escaped for a double-quoted XML attribute.
fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c => out.push(c),
        }
    }
    out
}

/// Groups single values into rows of [`PER_ROW`], to keep long arrays compact but readable.
fn rows<T: Copy>(values: impl Iterator<Item = T>) -> impl Iterator<Item = Vec<T>> {
    let mut values = values.peekable();
    std::iter::from_fn(move || {
        values.peek()?;
        Some(values.by_ref().take(PER_ROW).collect())
    })
}

/// One `<DataArray>`, one row of values per line.
fn write_array<W: Write, R: IntoIterator<Item = T>, T: Display>(
    w: &mut W,
    kind: &str,
    name: Option<&str>,
    components: usize,
    rows: impl Iterator<Item = R>,
) -> io::Result<()> {
    write!(w, r#"        <DataArray type="{kind}""#)?;
    if let Some(name) = name {
        write!(w, r#" Name="{}""#, escape(name))?;
    }
    if components > 1 {
        write!(w, r#" NumberOfComponents="{components}""#)?;
    }
    writeln!(w, r#" format="ascii">"#)?;
    for row in rows {
        write!(w, "         ")?;
        for value in row {
            write!(w, " {value}")?;
        }
        writeln!(w)?;
    }
    writeln!(w, "        </DataArray>")
}

/// Installs a panic hook that prints nothing for a panic inside the VTK reader (which
/// [`read_vtu`] turns into an error naming the file) and leaves every other panic to the hook
/// in place before. Installed once by the programs at start, so that no thread's hook is
/// swapped while another reads a file.
pub fn quiet_reader_panics() {
    let before = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        if info.location().is_some_and(|l| l.file().contains("vtkio")) {
            return;
        }
        before(info);
    }));
}

#[cfg(test)]
mod tests {
    use super::*;

    const POINTS: [[f64; 3]; 5] = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [1.0, 1.0, 1.0],
    ];
    const TETS: [[u32; 4]; 2] = [[0, 1, 2, 3], [1, 2, 4, 3]];

    /// The whitespace-separated contents of the data array called `name`.
    fn array<'a>(xml: &'a str, name: &str) -> Vec<&'a str> {
        let start = xml.find(&format!(r#"Name="{name}""#)).expect(name);
        let body = &xml[start..];
        let open = body.find('>').unwrap() + 1;
        let close = body.find("</DataArray>").unwrap();
        body[open..close].split_whitespace().collect()
    }

    #[test]
    fn two_tets_with_data() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.vtu");
        let displacement = [[0.5, 0.0, -0.25]; 5];
        let energy = [1.5, 1e-20];
        write_vtu(
            &path,
            &POINTS,
            &TETS,
            &[("displacement", &displacement)],
            &[("energy <J>", &energy)],
        )
        .unwrap();
        let xml = std::fs::read_to_string(&path).unwrap();
        assert!(xml.starts_with("<?xml"));
        assert!(xml.contains(r#"<VTKFile type="UnstructuredGrid""#));
        assert!(xml.contains(r#"<Piece NumberOfPoints="5" NumberOfCells="2">"#));
        assert!(xml.contains(r#"<PointData Vectors="displacement">"#));
        assert!(xml.contains(r#"<CellData Scalars="energy &lt;J&gt;">"#));
        assert_eq!(
            array(&xml, "connectivity"),
            ["0", "1", "2", "3", "1", "2", "4", "3"]
        );
        assert_eq!(array(&xml, "offsets"), ["4", "8"]);
        assert_eq!(array(&xml, "types"), ["10", "10"]);
        assert_eq!(array(&xml, "displacement").len(), 15);
        assert_eq!(array(&xml, "displacement")[..3], ["0.5", "0", "-0.25"]);
        assert_eq!(array(&xml, "energy &lt;J&gt;"), ["1.5", "1e-20"]);
        let points = xml.find("<Points>").unwrap();
        let values: Vec<f64> = xml[points..]
            .split("</DataArray>")
            .next()
            .and_then(|s| s.split_once(r#"format="ascii">"#))
            .unwrap()
            .1
            .split_whitespace()
            .map(|t| t.parse().unwrap())
            .collect();
        assert_eq!(values, POINTS.concat());
        for tag in [
            "UnstructuredGrid",
            "Piece",
            "PointData",
            "CellData",
            "Points",
            "Cells",
            "VTKFile",
        ] {
            assert_eq!(xml.matches(&format!("<{tag}")).count(), 1, "{tag}");
            assert_eq!(xml.matches(&format!("</{tag}>")).count(), 1, "{tag}");
        }
        assert_eq!(
            xml.matches("<DataArray").count(),
            xml.matches("</DataArray>").count()
        );
    }

    #[test]
    fn no_data_arrays() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.vtu");
        write_vtu(&path, &POINTS, &TETS, &[], &[]).unwrap();
        let xml = std::fs::read_to_string(&path).unwrap();
        assert!(!xml.contains("PointData") && !xml.contains("CellData"));
        assert_eq!(array(&xml, "types"), ["10", "10"]);
    }

    #[test]
    fn mismatched_or_bad_input_is_invalid_input() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.vtu");
        let short = [[0.0; 3]; 4];
        let bad = |r: io::Result<()>| {
            let err = r.unwrap_err();
            assert_eq!(err.kind(), io::ErrorKind::InvalidInput, "{err}");
            err.to_string()
        };
        let msg = bad(write_vtu(&path, &POINTS, &TETS, &[("u", &short)], &[]));
        assert!(msg.contains("4 values for 5 points"), "{msg}");
        let msg = bad(write_vtu(&path, &POINTS, &TETS, &[], &[("e", &[1.0])]));
        assert!(msg.contains("1 values for 2 tetrahedra"), "{msg}");
        bad(write_vtu(&path, &POINTS, &[[0, 1, 2, 5]], &[], &[]));
        bad(write_vtu(
            &path,
            &POINTS,
            &TETS,
            &[],
            &[("e", &[1.0, f64::NAN])],
        ));
        bad(write_vtu(
            &path,
            &POINTS,
            &TETS,
            &[],
            &[("e", &[1.0, 2.0]), ("e", &[1.0, 2.0])],
        ));
        bad(write_vtu(&path, &POINTS, &TETS, &[], &[("", &[1.0, 2.0])]));
        assert!(!path.exists(), "nothing is written on invalid input");
    }

    #[test]
    fn pvd_lists_the_steps() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("run.pvd");
        let steps = vec![
            (0.0, "f/step_0.vtu".to_owned()),
            (0.04, "f/step_1.vtu".to_owned()),
        ];
        write_pvd(&path, &steps).unwrap();
        let xml = std::fs::read_to_string(&path).unwrap();
        assert!(xml.contains(r#"<VTKFile type="Collection""#));
        assert!(xml.contains(r#"<DataSet timestep="0" group="" part="0" file="f/step_0.vtu"/>"#));
        assert!(
            xml.contains(r#"<DataSet timestep="0.04" group="" part="0" file="f/step_1.vtu"/>"#)
        );
        let err = write_pvd(&path, &[(f64::INFINITY, "a.vtu".to_owned())]).unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::InvalidInput);
    }

    #[test]
    fn read_back_what_write_vtu_wrote() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.vtu");
        let points = POINTS.map(|p| p.map(|c| c * 0.1 + 1e-3));
        write_vtu(&path, &points, &TETS, &[], &[]).unwrap();
        let m = read_vtu(&path).unwrap();
        assert_eq!(m.nodes, points);
        assert_eq!(m.tets, TETS);
        assert_eq!(m.skipped_cells, 0);
    }

    fn grid(cells: &str, types: &str) -> String {
        format!(
            r#"<?xml version="1.0"?>
<VTKFile type="UnstructuredGrid" version="0.1" byte_order="BigEndian">
  <UnstructuredGrid>
    <Piece NumberOfPoints="4" NumberOfCells="2">
      <Points>
        <DataArray type="Float32" NumberOfComponents="3" format="ascii">
          0 0 0 1 0 0 0 1 0 0 0 1
        </DataArray>
      </Points>
      <Cells>
        <DataArray type="Int32" Name="connectivity" format="ascii">{cells}</DataArray>
        <DataArray type="Int32" Name="offsets" format="ascii">3 7</DataArray>
        <DataArray type="UInt8" Name="types" format="ascii">{types}</DataArray>
      </Cells>
    </Piece>
  </UnstructuredGrid>
</VTKFile>
"#
        )
    }

    #[test]
    fn other_cells_are_skipped_and_bad_cells_named() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("g.vtu");
        // A triangle, then a tetrahedron.
        std::fs::write(&path, grid("0 1 2 0 1 2 3", "5 10")).unwrap();
        let m = read_vtu(&path).unwrap();
        assert_eq!(m.tets, vec![[0, 1, 2, 3]]);
        assert_eq!(m.skipped_cells, 1);
        assert_eq!(m.nodes[3], [0.0, 0.0, 1.0]);
        // A point that does not exist.
        std::fs::write(&path, grid("0 1 2 0 1 2 9", "5 10")).unwrap();
        let e = read_vtu(&path).unwrap_err();
        assert!(e.message.contains("point 9"), "{e}");
        // No tetrahedron at all.
        std::fs::write(&path, grid("0 1 2 0 1 2 3", "5 9")).unwrap();
        let e = read_vtu(&path).unwrap_err();
        assert!(e.message.contains("no tetrahedron"), "{e}");
        // Not a file.
        let e = read_vtu(&dir.path().join("none.vtu")).unwrap_err();
        assert!(e.to_string().contains("none.vtu"), "{e}");
    }

    /// SOFA's fine liver, read where it lies (see `shared/data/liver/SOURCE.md`).
    #[test]
    fn sofa_fine_liver() {
        let path =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/liver/liverFine.vtu");
        let m = read_vtu(&path).unwrap();
        assert_eq!(
            (m.nodes.len(), m.tets.len(), m.skipped_cells),
            (4293, 22019, 0)
        );
        // Centimetres, the frame of liver.msh: the first point of the file.
        assert_eq!(m.nodes[0], [-2.43563f32, 3.76782, 2.1424].map(f64::from));
    }
}
