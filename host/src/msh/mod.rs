//! Gmsh mesh files (`.msh`): read tetrahedral volume meshes, write them back.
//!
//! The reader takes the ASCII forms people have:
//! - version 1 (`$NOD` … `$ENDNOD`, `$ELM` … `$ENDELM`), e.g. SOFA's `liver.msh`;
//! - version 2.2 (`$MeshFormat` `2.2 0 8`, `$Nodes`, `$Elements`); 2.0 and 2.1 share its ASCII
//!   layout and are read the same way;
//! - version 4.1 (`$Nodes` and `$Elements` in entity blocks, node tags listed before their
//!   coordinates).
//!
//! Only 4-node tetrahedra (Gmsh element type 4) are kept, because the solver meshes volumes with
//! linear tetrahedra only. Every other element (points, lines, triangles, second-order
//! elements, …) is counted in [`MshMesh::skipped_elements`] and dropped. Sections the reader does
//! not need (`$PhysicalNames`, `$Entities`, `$NodeData`, …) are skipped whole. Binary files are
//! refused with a message saying to re-save them as ASCII.
//!
//! Node tags may have gaps and come in any order: the nodes are renumbered 0, 1, 2, … in the
//! order they appear, and the file's tags are kept in [`MshMesh::node_tags`]. All nodes are kept,
//! including any that no tetrahedron uses.
//!
//! Every error names the file and the 1-based line at which it was found, and no input makes the
//! reader panic.

use std::fmt;
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::Path;

mod lines;
mod sections;

use lines::{Lines, Section, quote, read_mesh_format};
use sections::{Elements, NodeTable, TET4, read_elements, read_nodes};

/// A tetrahedral mesh read from a Gmsh file.
///
/// What [`parse_msh`] and [`read_msh`] promise on return: `nodes.len() == node_tags.len()`, the
/// tags are distinct, every coordinate is finite, `tets` is not empty and every index in it is
/// below `nodes.len()`.
#[derive(Clone, Debug, PartialEq)]
pub struct MshMesh {
    /// Node positions in the file's length unit (nothing is converted; SOFA's liver is in
    /// centimetres), indexed 0-based in the order the nodes appear in the file.
    pub nodes: Vec<[f64; 3]>,
    /// The 4-node tetrahedra as 0-based indices into `nodes`, in file order and with the file's
    /// node order ([`MshMesh::orient_positive`] makes every volume positive).
    pub tets: Vec<[u32; 4]>,
    /// The file's tag of each node: `node_tags[i]` is the tag of `nodes[i]`.
    pub node_tags: Vec<u64>,
    /// The format version that was read.
    pub version: MshVersion,
    /// How many elements of other types than the 4-node tetrahedron were dropped.
    pub skipped_elements: usize,
}

/// The Gmsh file format versions the reader understands (all ASCII).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum MshVersion {
    /// Version 1: no `$MeshFormat`, sections `$NOD` and `$ELM`.
    V1,
    /// Version 2.2 (also 2.0 and 2.1, which share the ASCII layout): `$Nodes` and `$Elements`
    /// with one node or element per line.
    V2_2,
    /// Version 4.1: `$Nodes` and `$Elements` in entity blocks.
    V4_1,
}

/// Why a Gmsh file could not be read: the file, the 1-based line at which the problem was found
/// (0 when it is not tied to a line, e.g. the file cannot be opened) and what is wrong.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MshError {
    /// The file, as given to [`read_msh`] or [`parse_msh`].
    pub file: String,
    /// The 1-based line at which the problem was detected; 0 when no line applies. For a file
    /// that ends early, its last line.
    pub line: usize,
    /// What is wrong, naming the offending value or section.
    pub message: String,
}

impl fmt::Display for MshError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.line == 0 {
            write!(f, "{}: {}", self.file, self.message)
        } else {
            write!(f, "{}:{}: {}", self.file, self.line, self.message)
        }
    }
}

impl std::error::Error for MshError {}

/// Reads the Gmsh file at `path` (see [`parse_msh`] for what is accepted).
///
/// Bytes that are not UTF-8 are replaced rather than refused, so that a binary file reaches the
/// `$MeshFormat` check and gets its own message.
///
/// # Errors
/// An [`MshError`] with line 0 if the file cannot be read, otherwise those of [`parse_msh`].
pub fn read_msh(path: &Path) -> Result<MshMesh, MshError> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|e| MshError {
        file: file.clone(),
        line: 0,
        message: format!("cannot read: {e}"),
    })?;
    parse_msh(&String::from_utf8_lossy(&bytes), &file)
}

/// Parses the text of a Gmsh file (versions 1, 2.2 or 4.1, ASCII); `file` names it in errors.
///
/// Blank lines are ignored anywhere; leading and trailing spaces on a line too.
///
/// # Errors
/// An [`MshError`] naming `file` and the line where the problem was found: a binary file, an
/// unsupported version, a missing or repeated section, a file or section that ends before the
/// announced number of entries (the line where it ended), more entries than announced, a value
/// that is not a number (quoted), a coordinate that is NaN or infinite, a node tag defined twice,
/// an element naming a node tag that no node has, or no 4-node tetrahedron at all.
pub fn parse_msh(text: &str, file: &str) -> Result<MshMesh, MshError> {
    let mut lines = Lines::new(text, file);
    let version = read_mesh_format(&mut lines)?;
    let (nodes_name, elements_name) = match version {
        MshVersion::V1 => ("NOD", "ELM"),
        MshVersion::V2_2 | MshVersion::V4_1 => ("Nodes", "Elements"),
    };
    let mut table = NodeTable::default();
    let mut nodes_line: Option<usize> = None;
    let mut elements: Option<(Elements, usize)> = None;
    while let Some((at, text)) = lines.next_line() {
        let Some(name) = text.strip_prefix('$') else {
            return Err(at.error(format!(
                "expected a section header such as ${nodes_name}, found {}",
                quote(text)
            )));
        };
        let section = Section {
            name,
            line: at.line,
        };
        if name == nodes_name {
            if let Some(first) = nodes_line {
                return Err(at.error(format!(
                    "a second ${name} section (the first is at line {first})"
                )));
            }
            nodes_line = Some(at.line);
            read_nodes(version, &mut lines, &section, &mut table)?;
        } else if name == elements_name {
            if nodes_line.is_none() {
                return Err(at.error(format!("${name} comes before ${nodes_name}")));
            }
            if let Some((_, first)) = elements {
                return Err(at.error(format!(
                    "a second ${name} section (the first is at line {first})"
                )));
            }
            let read = read_elements(version, &mut lines, &section, &table)?;
            elements = Some((read, at.line));
        } else if name == "MeshFormat" {
            return Err(at.error("$MeshFormat must be the first section, and only one"));
        } else {
            lines.skip_section(&section)?;
        }
    }
    let end = lines.at_end();
    if nodes_line.is_none() {
        let hint = match version {
            MshVersion::V1 => " (a file without $MeshFormat is read as version 1)",
            MshVersion::V2_2 | MshVersion::V4_1 => "",
        };
        return Err(end.error(format!(
            "the file ends without a ${nodes_name} section{hint}"
        )));
    }
    let Some((elements, _)) = elements else {
        return Err(end.error(format!("the file ends without an ${elements_name} section")));
    };
    if elements.tets.is_empty() {
        return Err(elements.end.error(format!(
            "no 4-node tetrahedron (element type {TET4}) among the {} elements: a volume mesh is \
             needed",
            elements.skipped
        )));
    }
    Ok(MshMesh {
        nodes: table.coords,
        tets: elements.tets,
        node_tags: table.tags,
        version,
        skipped_elements: elements.skipped,
    })
}

/// Writes a tetrahedral mesh as a Gmsh version 2.2 ASCII file.
///
/// Node `i` gets tag `i + 1`, tetrahedron `k` element tag `k + 1`, with two element tags:
/// physical group 0 (none) and elementary entity 1. Coordinates are written in the shortest
/// decimal form that reads back to the same `f64` (positional for magnitudes in
/// `[1e-5, 1e15)`, otherwise scientific), so writing and reading back is bit-exact and the
/// output is the same for the same input.
///
/// # Errors
/// `InvalidInput` (and nothing written) if a coordinate is NaN or infinite or a tetrahedron
/// refers to a node index `>= nodes.len()`; otherwise the I/O errors of creating and writing
/// `path`.
pub fn write_msh22(path: &Path, nodes: &[[f64; 3]], tets: &[[u32; 4]]) -> io::Result<()> {
    let invalid = |message: String| io::Error::new(io::ErrorKind::InvalidInput, message);
    if let Some(i) = nodes.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        return Err(invalid(format!(
            "node {i} has a coordinate that is not finite"
        )));
    }
    for (k, tet) in tets.iter().enumerate() {
        if let Some(&v) = tet.iter().find(|&&v| v as usize >= nodes.len()) {
            return Err(invalid(format!(
                "tetrahedron {k} refers to node {v}, but there are {} nodes",
                nodes.len()
            )));
        }
    }
    let mut w = BufWriter::new(File::create(path)?);
    writeln!(w, "$MeshFormat\n2.2 0 8\n$EndMeshFormat")?;
    writeln!(w, "$Nodes\n{}", nodes.len())?;
    for (i, p) in nodes.iter().enumerate() {
        let [x, y, z] = p.map(RoundTrip);
        writeln!(w, "{} {x} {y} {z}", i + 1)?;
    }
    writeln!(w, "$EndNodes")?;
    writeln!(w, "$Elements\n{}", tets.len())?;
    for (k, t) in tets.iter().enumerate() {
        let [a, b, c, d] = t.map(|v| u64::from(v) + 1);
        writeln!(w, "{} {TET4} 2 0 1 {a} {b} {c} {d}", k + 1)?;
    }
    writeln!(w, "$EndElements")?;
    w.flush()
}

impl MshMesh {
    /// Swaps the last two nodes of every tetrahedron whose signed volume is negative, so that
    /// every non-degenerate tetrahedron has `(b - a) · ((c - a) × (d - a)) > 0`; returns how
    /// many were flipped.
    ///
    /// Degenerate (zero-volume) tetrahedra are left as they are, and so is one whose indices
    /// are out of range (which a mesh from [`parse_msh`] does not have).
    pub fn orient_positive(&mut self) -> usize {
        let mut flipped = 0;
        for tet in &mut self.tets {
            let corners = tet.map(|v| self.nodes.get(v as usize).copied());
            let [Some(a), Some(b), Some(c), Some(d)] = corners else {
                continue;
            };
            if six_signed_volume(a, b, c, d) < 0.0 {
                tet.swap(2, 3);
                flipped += 1;
            }
        }
        flipped
    }
}

/// Six times the signed volume of the tetrahedron `(a, b, c, d)`.
fn six_signed_volume(a: [f64; 3], b: [f64; 3], c: [f64; 3], d: [f64; 3]) -> f64 {
    let sub = |p: [f64; 3]| [p[0] - a[0], p[1] - a[1], p[2] - a[2]];
    let (u, v, w) = (sub(b), sub(c), sub(d));
    let cross = [
        v[1] * w[2] - v[2] * w[1],
        v[2] * w[0] - v[0] * w[2],
        v[0] * w[1] - v[1] * w[0],
    ];
    u[0] * cross[0] + u[1] * cross[1] + u[2] * cross[2]
}

/// Formats an `f64` in the shortest decimal form that parses back to the same value:
/// positional for magnitudes in `[1e-5, 1e15)` and zero, scientific otherwise (positional
/// `1e-300` would be 300 digits long). Shared with the VTU writer.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RoundTrip(pub(crate) f64);

impl fmt::Display for RoundTrip {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let x = self.0;
        // Both `{}` and `{:e}` without a precision print the shortest round-trip digits.
        if x == 0.0 || !x.is_finite() || (1e-5..1e15).contains(&x.abs()) {
            write!(f, "{x}")
        } else {
            write!(f, "{x:e}")
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    /// Two tetrahedra sharing the face (20, 30, 40), node tags with gaps, one point and one
    /// triangle element to skip; the second tetrahedron is negatively oriented.
    const V22: &str = "$MeshFormat
2.2 0 8
$EndMeshFormat
$PhysicalNames
2
2 1 \"skin\"
3 2 \"liver\"
$EndPhysicalNames
$Nodes
5
10 0 0 0
20 1 0 0
30 0 1 0
40 0 0 1
50 1 1 1
$EndNodes
$Elements
4
1 15 2 0 1 10
2 2 2 1 1 10 20 30
3 4 2 2 1 10 20 30 40
4 4 3 2 1 0 30 20 40 50
$EndElements
$Comments
anything $here
$EndComments
";

    /// The same mesh in version 4.1: three node blocks, one of them parametric.
    const V41: &str = "$MeshFormat
4.1 0 8
$EndMeshFormat
$Entities
1 0 1 1
1 0 0 0 0
1 0 0 0 1 1 0 1 1 0
1 0 0 0 1 1 1 1 2 1 1
$EndEntities
$Nodes
3 5 10 50
0 1 0 1
10
0 0 0
2 1 1 1
20
1 0 0 0.25 0.75
3 1 0 3
30
40
50
0 1 0
0 0 1
1 1 1
$EndNodes
$Elements
3 4 1 4
0 1 15 1
1 10
2 1 2 1
2 10 20 30
3 1 4 2
3 10 20 30 40
4 30 20 40 50
$EndElements
";

    fn parse(text: &str) -> Result<MshMesh, MshError> {
        parse_msh(text, "t.msh")
    }

    fn liver_path() -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/liver/liver.msh")
    }

    #[test]
    fn reads_sofa_liver_version_1() {
        let path = liver_path();
        if !path.exists() {
            eprintln!(
                "skipped: {} is absent (SOFA's share/mesh/liver.msh)",
                path.display()
            );
            return;
        }
        let mut mesh = read_msh(&path).unwrap();
        assert_eq!(mesh.version, MshVersion::V1);
        assert_eq!(mesh.nodes.len(), 181);
        assert_eq!(mesh.tets.len(), 596);
        assert_eq!(mesh.skipped_elements, 0);
        assert_eq!(mesh.node_tags, (1..=181).collect::<Vec<u64>>());
        assert_eq!(mesh.nodes[0], [-0.979259, 2.23512, 2.61245]);
        let flipped = mesh.orient_positive();
        eprintln!("liver: {flipped} of 596 tetrahedra flipped");
        for t in &mesh.tets {
            let [a, b, c, d] = t.map(|v| mesh.nodes[v as usize]);
            assert!(six_signed_volume(a, b, c, d) > 0.0, "tet {t:?}");
        }
        assert_eq!(mesh.orient_positive(), 0);
    }

    #[test]
    fn versions_2_2_and_4_1_agree() {
        let a = parse(V22).unwrap();
        let b = parse(V41).unwrap();
        assert_eq!((a.version, b.version), (MshVersion::V2_2, MshVersion::V4_1));
        assert_eq!(a.node_tags, [10, 20, 30, 40, 50]);
        assert_eq!(a.nodes[4], [1.0, 1.0, 1.0]);
        assert_eq!(a.tets, [[0, 1, 2, 3], [2, 1, 3, 4]]);
        assert_eq!(a.skipped_elements, 2);
        assert_eq!(
            (&a.nodes, &a.tets, &a.node_tags),
            (&b.nodes, &b.tets, &b.node_tags)
        );
        assert_eq!(a.skipped_elements, b.skipped_elements);
    }

    #[test]
    fn version_1_and_crlf() {
        let text = "$NOD\r\n3\r\n7 0 0 0\r\n3 1 0 0\r\n9 0 1 0\r\n\r\n$ENDNOD\r\n$ELM\r\n2\r\n\
                    1 4 1 1 4 7 3 9 7\r\n2 2 1 1 3 7 3 9\r\n$ENDELM\r\n";
        let mesh = parse(text).unwrap();
        assert_eq!(mesh.version, MshVersion::V1);
        assert_eq!(mesh.node_tags, [7, 3, 9]);
        assert_eq!(mesh.tets, [[0, 1, 2, 0]]);
        assert_eq!(mesh.skipped_elements, 1);
    }

    #[test]
    fn orient_positive_flips_the_negative_tet() {
        let mut mesh = parse(V22).unwrap();
        assert_eq!(mesh.orient_positive(), 1);
        assert_eq!(mesh.tets[1], [2, 1, 4, 3]);
        assert_eq!(mesh.orient_positive(), 0);
    }

    #[test]
    fn write_then_read_is_bit_exact() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.msh");
        let mut rng = Rng::new(7);
        let special = [
            0.0,
            -0.0,
            0.1,
            1.0 / 3.0,
            1e-5,
            9.999999999999999e-6,
            1e15,
            999999999999999.9,
            1e-300,
            5e-324,
            f64::MIN_POSITIVE,
            f64::MAX,
            -f64::MAX,
            f64::EPSILON,
        ];
        let mut nodes: Vec<[f64; 3]> = special.iter().map(|&s| [s, -s, 1.0]).collect();
        for _ in 0..200 {
            let scale = 10f64.powi((rng.uniform() * 60.0) as i32 - 30);
            nodes.push([rng.normal() * scale, rng.normal(), rng.range(-1e3, 1e3)]);
        }
        let n = nodes.len() as u32;
        let tets: Vec<[u32; 4]> = (0..50)
            .map(|k| [k, (k + 1) % n, (k + 7) % n, (k + 13) % n])
            .collect();
        write_msh22(&path, &nodes, &tets).unwrap();
        let back = read_msh(&path).unwrap();
        assert_eq!(back.version, MshVersion::V2_2);
        assert_eq!(back.tets, tets);
        assert_eq!(back.node_tags, (1..=u64::from(n)).collect::<Vec<_>>());
        let bits = |v: &[[f64; 3]]| {
            v.iter()
                .flat_map(|p| p.map(f64::to_bits))
                .collect::<Vec<_>>()
        };
        assert_eq!(bits(&back.nodes), bits(&nodes));
        // Deterministic: the same input writes the same bytes.
        let again = dir.path().join("again.msh");
        write_msh22(&again, &nodes, &tets).unwrap();
        assert_eq!(
            std::fs::read(&path).unwrap(),
            std::fs::read(&again).unwrap()
        );
    }

    #[test]
    fn write_refuses_bad_input() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.msh");
        let nodes = [[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let err = write_msh22(&path, &nodes, &[[0, 1, 2, 4]]).unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::InvalidInput);
        let err = write_msh22(&path, &[[f64::NAN, 0.0, 0.0]], &[]).unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::InvalidInput);
        assert!(!path.exists());
    }

    /// Parses `text`, expecting an error at `line` whose message contains every one of `words`.
    fn assert_error(text: &str, line: usize, words: &[&str]) {
        let err = parse(text).unwrap_err();
        assert_eq!(err.file, "t.msh");
        assert_eq!(err.line, line, "{err}");
        for w in words {
            assert!(err.message.contains(w), "{err} does not mention {w}");
        }
        assert_eq!(err.to_string(), format!("t.msh:{line}: {}", err.message));
    }

    #[test]
    fn truncated_node_block() {
        // Announces 5 nodes, the file ends (line 8) after 3.
        let text =
            "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n5\n10 0 0 0\n20 1 0 0\n30 0 1 0\n";
        assert_error(text, 8, &["ends", "node 4 of 5"]);
        // With the end marker present, the error is at the marker.
        let text =
            "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n5\n10 0 0 0\n20 1 0 0\n$EndNodes\n";
        assert_error(text, 8, &["$EndNodes", "node 3 of 5", "fewer"]);
        // Version 4.1: coordinates missing after the tags.
        let cut = V41.find("0 1 0\n0 0 1").unwrap();
        let lines = V41[..cut].lines().count();
        assert_error(&V41[..cut], lines, &["ends", "coordinates of node 1 of 3"]);
    }

    #[test]
    fn non_numeric_coordinate() {
        let text = V22.replace("20 1 0 0", "20 1 0x 0");
        assert_error(&text, 12, &["y coordinate", "node 20", "\"0x\""]);
        let text = V22.replace("20 1 0 0", "20 1 nan 0");
        assert_error(&text, 12, &["y coordinate", "finite"]);
        let text = V41.replace("1 0 0 0.25 0.75", "1 0 -inf 0.25 0.75");
        assert_error(&text, 17, &["z coordinate", "node 20", "finite"]);
    }

    #[test]
    fn unknown_node_tag() {
        let text = V22.replace("3 4 2 2 1 10 20 30 40", "3 4 2 2 1 10 20 30 60");
        assert_error(&text, 21, &["element 3", "node tag 60"]);
        let text = V41.replace("4 30 20 40 50", "4 30 20 40 51");
        assert_error(&text, 34, &["element 4", "node tag 51"]);
    }

    #[test]
    fn unsupported_version_and_binary() {
        assert_error(
            &V41.replacen("4.1 0 8", "3.0 0 8", 1),
            2,
            &["unsupported", "\"3.0\""],
        );
        assert_error(
            &V41.replacen("4.1 0 8", "4 0 8", 1),
            2,
            &["unsupported", "\"4\""],
        );
        assert_error(
            &V41.replacen("4.1 0 8", "4.1 1 8", 1),
            2,
            &["binary", "ASCII"],
        );
        // A real binary file: the version line, then raw bytes.
        let mut bytes = b"$MeshFormat\n4.1 1 8\n".to_vec();
        bytes.extend([1, 0, 0, 0, 0xff, 0xfe, b'\n', 0x80]);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("b.msh");
        std::fs::write(&path, &bytes).unwrap();
        let err = read_msh(&path).unwrap_err();
        assert_eq!(
            (err.line, err.message.contains("binary")),
            (2, true),
            "{err}"
        );
    }

    #[test]
    fn other_errors() {
        // Missing sections.
        assert_error(
            "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n",
            3,
            &["without a $Nodes"],
        );
        let no_elements = &V22[..V22.find("$Elements").unwrap()];
        assert_error(no_elements, 16, &["without an $Elements"]);
        assert_error("", 1, &["$NOD", "version 1"]);
        // More node lines than announced.
        assert_error(
            &V22.replace("\n5\n10", "\n4\n10"),
            15,
            &["$EndNodes", "more"],
        );
        // Counts in 4.1 that do not add up.
        assert_error(
            &V41.replace("3 5 10 50", "3 4 10 50"),
            18,
            &["more nodes", "4"],
        );
        assert_error(&V41.replace("3 4 1 4", "3 5 1 4"), 34, &["4 elements", "5"]);
        // Duplicate tag, bad count, element before nodes, no tetrahedra, skipped sections.
        assert_error(
            &V22.replace("30 0 1 0", "20 0 1 0"),
            13,
            &["node tag 20", "twice"],
        );
        assert_error(
            &V22.replace("\n5\n10", "\nfive\n10"),
            10,
            &["number of nodes", "\"five\""],
        );
        let swapped = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Elements\n0\n$EndElements\n";
        assert_error(swapped, 4, &["before $Nodes"]);
        let flat = V22
            .replace("3 4 2 2 1", "3 2 2 2 1")
            .replace("4 4 3 2 1 0", "4 2 3 2 1 0");
        assert_error(&flat, 23, &["no 4-node tetrahedron", "4 elements"]);
        assert_error(
            &V22.replace("$EndComments\n", ""),
            25,
            &["$Comments", "$EndComments"],
        );
        assert_error(
            &V22.replace("1 15 2 0 1 10", "1 15 5 0 1 10"),
            19,
            &["5 tags"],
        );
        assert_error(
            &V22.replace("10 20 30 40", "10 20 30"),
            21,
            &["4 node tags"],
        );
    }

    #[test]
    fn never_panics_on_damaged_input() {
        // Every prefix of both files, and random damage to them, gives Ok or Err.
        for text in [V22, V41] {
            for (cut, _) in text.char_indices() {
                let _ = parse(&text[..cut]);
            }
            let mut rng = Rng::new(3);
            let junk = [
                "",
                "-1",
                "x",
                "$Nodes",
                "1e999",
                "18446744073709551616",
                "0",
                "4",
                "$End",
            ];
            for _ in 0..2000 {
                let mut tokens: Vec<String> = text.split(' ').map(str::to_owned).collect();
                let i = (rng.next_u64() % tokens.len() as u64) as usize;
                tokens[i] = junk[(rng.next_u64() % junk.len() as u64) as usize].to_owned();
                let _ = parse(&tokens.join(" "));
            }
        }
    }

    #[test]
    fn io_error_has_no_line() {
        let err = read_msh(Path::new("/nonexistent/x.msh")).unwrap_err();
        assert_eq!(err.line, 0);
        assert!(
            err.to_string()
                .starts_with("/nonexistent/x.msh: cannot read")
        );
    }
}
