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

use std::collections::HashMap;
use std::collections::hash_map::Entry;
use std::fmt;
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::Path;

/// A Gmsh element type: its number (the same in every version), how many nodes an element of
/// it lists, and its name.
struct ElementType {
    number: i64,
    nodes: usize,
    name: &'static str,
}

/// The element types the reader keeps, for every version alike: the 4-node (linear)
/// tetrahedron only, because the solver meshes volumes with linear tetrahedra. An element of
/// any other type is counted and skipped unread, whatever its nodes (the reader does not judge
/// what it drops).
const KEPT: [ElementType; 1] = [ElementType {
    number: 4,
    nodes: 4,
    name: "tetrahedron",
}];

/// Gmsh's element type number of the 4-node tetrahedron.
const TET4: i64 = KEPT[0].number;

/// The entry of [`KEPT`] for element type `number`, if elements of it are kept.
fn kept_type(number: i64) -> Option<&'static ElementType> {
    KEPT.iter().find(|t| t.number == number)
}

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
            match version {
                MshVersion::V4_1 => read_nodes_v41(&mut lines, &section, &mut table)?,
                MshVersion::V1 | MshVersion::V2_2 => {
                    read_nodes_v12(&mut lines, &section, &mut table)?
                }
            }
        } else if name == elements_name {
            if nodes_line.is_none() {
                return Err(at.error(format!("${name} comes before ${nodes_name}")));
            }
            if let Some((_, first)) = elements {
                return Err(at.error(format!(
                    "a second ${name} section (the first is at line {first})"
                )));
            }
            let read = match version {
                MshVersion::V1 => read_elements(&mut lines, &section, &table, element_v1)?,
                MshVersion::V2_2 => read_elements(&mut lines, &section, &table, element_v2)?,
                MshVersion::V4_1 => read_elements_v41(&mut lines, &section, &table)?,
            };
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

// ---------------------------------------------------------------------------------------------
// Reading, one line at a time. Every Gmsh ASCII layout puts one node, one element or one block
// header per line, so lines (not a token stream) are the unit: a truncated section is then found
// at its end marker instead of reading on into the next section.

/// A place in the file, for errors.
#[derive(Clone, Copy)]
struct At<'a> {
    file: &'a str,
    line: usize,
}

impl At<'_> {
    fn error(self, message: impl Into<String>) -> MshError {
        MshError {
            file: self.file.to_owned(),
            line: self.line,
            message: message.into(),
        }
    }

    /// A count or index (`usize`).
    fn count(self, token: &str, what: &str) -> Result<usize, MshError> {
        token.parse().map_err(|_| {
            self.error(format!(
                "the {what} is {}, not a non-negative integer",
                quote(token)
            ))
        })
    }

    /// A node or element tag (`u64`).
    fn tag(self, token: &str, what: &str) -> Result<u64, MshError> {
        token.parse().map_err(|_| {
            self.error(format!(
                "the {what} is {}, not a non-negative integer",
                quote(token)
            ))
        })
    }

    /// A signed integer whose value does not matter (entity tags); checked so that a corrupt
    /// line is noticed.
    fn int(self, token: &str, what: &str) -> Result<i64, MshError> {
        token
            .parse()
            .map_err(|_| self.error(format!("the {what} is {}, not an integer", quote(token))))
    }

    /// The three coordinates of a node, finite.
    fn coords(self, tokens: [&str; 3], tag: Option<u64>) -> Result<[f64; 3], MshError> {
        let mut out = [0.0; 3];
        let node = tag.map_or(String::new(), |t| format!(" of node {t}"));
        for ((slot, token), axis) in out.iter_mut().zip(tokens).zip(["x", "y", "z"]) {
            let value: f64 = token.parse().map_err(|_| {
                self.error(format!(
                    "the {axis} coordinate{node} is {}, not a number",
                    quote(token)
                ))
            })?;
            if !value.is_finite() {
                return Err(self.error(format!(
                    "the {axis} coordinate{node} is {}, not a finite number",
                    quote(token)
                )));
            }
            *slot = value;
        }
        Ok(out)
    }
}

/// A token or line for an error message: quoted with escapes, cut short if long (so that
/// binary garbage gives a readable message).
fn quote(text: &str) -> String {
    const MAX: usize = 40;
    match text.char_indices().nth(MAX) {
        Some((cut, _)) => format!("{:?}…", &text[..cut]),
        None => format!("{text:?}"),
    }
}

/// A section being read: its name without `$` and the line of its header.
struct Section<'a> {
    name: &'a str,
    line: usize,
}

impl Section<'_> {
    fn is_end(&self, text: &str) -> bool {
        // Version 1 writes `$ENDNOD`, later versions `$EndNodes`.
        text.strip_prefix("$End")
            .or_else(|| text.strip_prefix("$END"))
            .or_else(|| text.strip_prefix("$end"))
            .is_some_and(|rest| rest.eq_ignore_ascii_case(self.name))
    }
}

/// The non-blank lines of the file, trimmed, with their 1-based numbers.
struct Lines<'a> {
    file: &'a str,
    iter: std::iter::Enumerate<std::str::Lines<'a>>,
    /// The number of the file's last line (1 for an empty file), where a truncation is reported.
    last_line: usize,
    /// The number of the line returned last (0 before the first).
    current: usize,
}

impl<'a> Lines<'a> {
    fn new(text: &'a str, file: &'a str) -> Self {
        Lines {
            file,
            iter: text.lines().enumerate(),
            last_line: text.lines().count().max(1),
            current: 0,
        }
    }

    fn next_line(&mut self) -> Option<(At<'a>, &'a str)> {
        for (i, text) in self.iter.by_ref() {
            let text = text.trim();
            if !text.is_empty() {
                self.current = i + 1;
                return Some((
                    At {
                        file: self.file,
                        line: i + 1,
                    },
                    text,
                ));
            }
        }
        None
    }

    fn at_end(&self) -> At<'a> {
        At {
            file: self.file,
            line: self.last_line,
        }
    }

    fn at_current(&self) -> At<'a> {
        At {
            file: self.file,
            line: self.current.max(1),
        }
    }

    /// The next content line of `section`; `expecting` says what it should hold, for the error
    /// when the section or the file ends first.
    fn content(
        &mut self,
        section: &Section<'_>,
        expecting: impl FnOnce() -> String,
    ) -> Result<(At<'a>, &'a str), MshError> {
        match self.next_line() {
            None => Err(self.at_end().error(format!(
                "the file ends inside ${} (opened at line {}) while expecting {}",
                section.name,
                section.line,
                expecting()
            ))),
            Some((at, text)) if section.is_end(text) => Err(at.error(format!(
                "{text} while expecting {}: the section holds fewer entries than announced",
                expecting()
            ))),
            Some((at, text)) if text.starts_with('$') => Err(at.error(format!(
                "{text} inside ${} while expecting {} (is $End{} missing?)",
                section.name,
                expecting(),
                section.name
            ))),
            Some(found) => Ok(found),
        }
    }

    /// Reads the end marker of `section`, which must come right after `after` (say, "5 nodes").
    fn end(
        &mut self,
        section: &Section<'_>,
        after: impl FnOnce() -> String,
    ) -> Result<At<'a>, MshError> {
        match self.next_line() {
            None => Err(self.at_end().error(format!(
                "the file ends inside ${} (opened at line {}): $End{} is missing",
                section.name, section.line, section.name
            ))),
            Some((at, text)) if section.is_end(text) => Ok(at),
            Some((at, text)) if text.starts_with('$') => Err(at.error(format!(
                "{text} inside ${}: $End{} is missing",
                section.name, section.name
            ))),
            Some((at, text)) => Err(at.error(format!(
                "expected $End{} after {}, found {}: the section holds more entries than announced",
                section.name,
                after(),
                quote(text)
            ))),
        }
    }

    /// Skips a section the reader does not need, up to its end marker.
    fn skip_section(&mut self, section: &Section<'_>) -> Result<(), MshError> {
        while let Some((_, text)) = self.next_line() {
            if section.is_end(text) {
                return Ok(());
            }
        }
        Err(self.at_end().error(format!(
            "the file ends inside ${} (opened at line {}): $End{} is missing",
            section.name, section.line, section.name
        )))
    }
}

/// Reads `$MeshFormat` if the file starts with it; a file that does not is version 1.
fn read_mesh_format(lines: &mut Lines<'_>) -> Result<MshVersion, MshError> {
    // Peek on a copy: a version 1 file's first line belongs to its first section.
    let mut peek = Lines {
        iter: lines.iter.clone(),
        ..*lines
    };
    match peek.next_line() {
        Some((_, "$MeshFormat")) => {}
        _ => return Ok(MshVersion::V1),
    }
    *lines = peek;
    let section = Section {
        name: "MeshFormat",
        line: lines.current,
    };
    let (at, text) = lines.content(&section, || "the version line (e.g. \"4.1 0 8\")".into())?;
    let tokens: Vec<&str> = text.split_whitespace().collect();
    let [version, file_type, data_size] = tokens.as_slice() else {
        return Err(at.error(format!(
            "the $MeshFormat line holds 3 values (version file-type data-size), found {}",
            quote(text)
        )));
    };
    // The file type first: a binary file gets the same advice whatever its version.
    match *file_type {
        "0" => {}
        "1" => return Err(at.error("binary Gmsh files are not supported; re-save as ASCII")),
        other => {
            return Err(at.error(format!(
                "the file type is {}, not 0 (ASCII) or 1 (binary)",
                quote(other)
            )));
        }
    }
    at.count(data_size, "data size")?;
    let version = match *version {
        "2" | "2.0" | "2.1" | "2.2" => MshVersion::V2_2,
        "4.1" => MshVersion::V4_1,
        other => {
            return Err(at.error(format!(
                "unsupported Gmsh format version {}: versions 1, 2.2 and 4.1 (ASCII) are read; \
                 re-save as 4.1 or 2.2",
                quote(other)
            )));
        }
    };
    lines.end(&section, || "the version line".into())?;
    Ok(version)
}

/// The nodes read so far, renumbered in order of appearance.
#[derive(Default)]
struct NodeTable {
    coords: Vec<[f64; 3]>,
    tags: Vec<u64>,
    index: HashMap<u64, u32>,
}

impl NodeTable {
    /// Gives the next index to `tag`. Its coordinates follow with [`NodeTable::push_coords`]
    /// (at once in versions 1 and 2, after the block's tags in version 4.1).
    fn add_tag(&mut self, at: At<'_>, tag: u64) -> Result<(), MshError> {
        let Ok(index) = u32::try_from(self.tags.len()) else {
            return Err(at.error("more than 2^32 nodes"));
        };
        match self.index.entry(tag) {
            Entry::Occupied(_) => Err(at.error(format!("node tag {tag} is defined twice"))),
            Entry::Vacant(slot) => {
                slot.insert(index);
                self.tags.push(tag);
                Ok(())
            }
        }
    }

    /// Sets the coordinates of the first node given a tag but no coordinates yet.
    fn push_coords(&mut self, at: At<'_>, tokens: [&str; 3]) -> Result<(), MshError> {
        let tag = self.tags.get(self.coords.len()).copied();
        let p = at.coords(tokens, tag)?;
        self.coords.push(p);
        Ok(())
    }

    /// The tetrahedron `element` whose node tags are `tokens` (four, as [`KEPT`]
    /// checked), as 0-based node indices.
    fn tet(&self, at: At<'_>, element: u64, tokens: &[&str]) -> Result<[u32; 4], MshError> {
        let mut out = [0; 4];
        for (slot, token) in out.iter_mut().zip(tokens) {
            let tag = at.tag(token, "node tag")?;
            *slot = *self.index.get(&tag).ok_or_else(|| {
                at.error(format!(
                    "element {element} refers to node tag {tag}, which no node has"
                ))
            })?;
        }
        Ok(out)
    }
}

/// What an element section gave.
struct Elements<'a> {
    tets: Vec<[u32; 4]>,
    skipped: usize,
    /// The end marker, where "no tetrahedron" is reported.
    end: At<'a>,
}

/// One element as a line of any version gives it.
struct Element<'t> {
    tag: u64,
    /// Gmsh's element type number.
    kind: i64,
    /// Its node tags, as written.
    nodes: &'t [&'t str],
}

/// The elements of a section as they are read: the tetrahedra kept, the others counted.
struct ElementReader<'n> {
    table: &'n NodeTable,
    tets: Vec<[u32; 4]>,
    skipped: usize,
}

impl<'n> ElementReader<'n> {
    fn new(table: &'n NodeTable) -> Self {
        ElementReader {
            table,
            tets: Vec::new(),
            skipped: 0,
        }
    }

    /// Keeps `e` if its type is in [`KEPT`] (its node count checked), or counts it as
    /// skipped.
    fn add(&mut self, at: At<'_>, e: Element<'_>) -> Result<(), MshError> {
        let Some(t) = kept_type(e.kind) else {
            self.skipped += 1;
            return Ok(());
        };
        if e.nodes.len() != t.nodes {
            return Err(at.error(format!(
                "{} {} (element type {}) needs {} node tags, the line gives {}",
                t.name,
                e.tag,
                t.number,
                t.nodes,
                e.nodes.len()
            )));
        }
        self.tets.push(self.table.tet(at, e.tag, e.nodes)?);
        Ok(())
    }

    fn finish(self, end: At<'_>) -> Elements<'_> {
        Elements {
            tets: self.tets,
            skipped: self.skipped,
            end,
        }
    }
}

/// The whitespace-separated values of a line.
fn split(text: &str) -> Vec<&str> {
    text.split_whitespace().collect()
}

/// A line that holds a single count, such as the number of nodes.
fn single_count(at: At<'_>, text: &str, what: &str) -> Result<usize, MshError> {
    match split(text).as_slice() {
        [token] => at.count(token, what),
        _ => Err(at.error(format!(
            "expected the {what} alone on the line, found {}",
            quote(text)
        ))),
    }
}

/// `$NOD` (version 1) and `$Nodes` (version 2): a count, then `tag x y z` per line.
fn read_nodes_v12(
    lines: &mut Lines<'_>,
    section: &Section<'_>,
    table: &mut NodeTable,
) -> Result<(), MshError> {
    let (at, text) = lines.content(section, || "the number of nodes".into())?;
    let n = single_count(at, text, "number of nodes")?;
    for i in 0..n {
        let (at, text) = lines.content(section, || format!("node {} of {n}", i + 1))?;
        let tokens = split(text);
        let &[tag, x, y, z] = tokens.as_slice() else {
            return Err(at.error(format!(
                "a node line holds 4 values (tag x y z), this one {}",
                tokens.len()
            )));
        };
        table.add_tag(at, at.tag(tag, "node tag")?)?;
        table.push_coords(at, [x, y, z])?;
    }
    lines.end(section, || format!("{n} nodes"))?;
    Ok(())
}

/// `$ELM` (version 1) and `$Elements` (version 2): a count, then one element per line, read by
/// `element` (the version's layout of the line).
fn read_elements<'a>(
    lines: &mut Lines<'a>,
    section: &Section<'_>,
    table: &NodeTable,
    element: for<'t> fn(At<'_>, &'t [&'t str]) -> Result<Element<'t>, MshError>,
) -> Result<Elements<'a>, MshError> {
    let (at, text) = lines.content(section, || "the number of elements".into())?;
    let n = single_count(at, text, "number of elements")?;
    let mut read = ElementReader::new(table);
    for i in 0..n {
        let (at, text) = lines.content(section, || format!("element {} of {n}", i + 1))?;
        let tokens = split(text);
        read.add(at, element(at, &tokens)?)?;
    }
    let end = lines.end(section, || format!("{n} elements"))?;
    Ok(read.finish(end))
}

/// A version 1 element line: `tag type physical elementary node-count nodes…`.
fn element_v1<'t>(at: At<'_>, tokens: &'t [&'t str]) -> Result<Element<'t>, MshError> {
    let [tag, kind, physical, elementary, count, nodes @ ..] = tokens else {
        return Err(at.error(format!(
            "a version 1 element line starts with 5 values (tag type physical elementary \
             node-count), this one holds {}",
            tokens.len()
        )));
    };
    let tag = at.tag(tag, "element tag")?;
    let kind = at.int(kind, "element type")?;
    at.int(physical, "physical region")?;
    at.int(elementary, "elementary region")?;
    let count = at.count(count, "number of nodes")?;
    if nodes.len() != count {
        return Err(at.error(format!(
            "element {tag} announces {count} nodes but lists {}",
            nodes.len()
        )));
    }
    Ok(Element { tag, kind, nodes })
}

/// A version 2 element line: `tag type tag-count tags… nodes…`.
fn element_v2<'t>(at: At<'_>, tokens: &'t [&'t str]) -> Result<Element<'t>, MshError> {
    let [tag, kind, tag_count, rest @ ..] = tokens else {
        return Err(at.error(format!(
            "an element line starts with 3 values (tag type number-of-tags), this one holds {}",
            tokens.len()
        )));
    };
    let tag = at.tag(tag, "element tag")?;
    let kind = at.int(kind, "element type")?;
    let tag_count = at.count(tag_count, "number of tags")?;
    let Some(nodes) = rest.get(tag_count..) else {
        return Err(at.error(format!(
            "element {tag} announces {tag_count} tags but the line holds only {} values after \
             the count",
            rest.len()
        )));
    };
    if let Some(bad) = rest
        .iter()
        .take(tag_count)
        .find(|t| t.parse::<i64>().is_err())
    {
        return Err(at.error(format!(
            "a tag of element {tag} is {}, not an integer",
            quote(bad)
        )));
    }
    Ok(Element { tag, kind, nodes })
}

/// The header line of a version 4.1 `$Nodes` or `$Elements` section:
/// `numEntityBlocks numEntries minTag maxTag`; returns the first two.
fn block_section_header(at: At<'_>, text: &str, entries: &str) -> Result<(usize, usize), MshError> {
    let tokens = split(text);
    let &[blocks, total, min, max] = tokens.as_slice() else {
        return Err(at.error(format!(
            "the header holds 4 values (numEntityBlocks num{entries} minTag maxTag), found {}",
            quote(text)
        )));
    };
    let blocks = at.count(blocks, "number of entity blocks")?;
    let total = at.count(total, &format!("number of {}", entries.to_lowercase()))?;
    at.tag(min, "smallest tag")?;
    at.tag(max, "largest tag")?;
    Ok((blocks, total))
}

/// The header line of a version 4.1 entity block: `entityDim entityTag x count`, where `x` is
/// `parametric` (nodes) or the element type (elements); returns the dimension, `x` as written
/// and the count.
fn block_header<'t>(
    at: At<'_>,
    text: &'t str,
    x: &str,
) -> Result<(usize, &'t str, usize), MshError> {
    let tokens = split(text);
    let &[dim, entity, value, count] = tokens.as_slice() else {
        return Err(at.error(format!(
            "an entity block header holds 4 values (entityDim entityTag {x} count), found {}",
            quote(text)
        )));
    };
    let dim = at.count(dim, "entity dimension")?;
    if dim > 3 {
        return Err(at.error(format!("the entity dimension is {dim}, not 0 to 3")));
    }
    at.int(entity, "entity tag")?;
    Ok((
        dim,
        value,
        at.count(count, "number of entries in the block")?,
    ))
}

/// Adds `count` to `seen`, failing if more than `total` (announced at line `line`) result.
fn add_to_total(
    at: At<'_>,
    seen: usize,
    count: usize,
    total: usize,
    line: usize,
    what: &str,
) -> Result<usize, MshError> {
    seen.checked_add(count)
        .filter(|&s| s <= total)
        .ok_or_else(|| {
            at.error(format!(
                "the blocks hold more {what} than the {total} announced at line {line}"
            ))
        })
}

/// `$Nodes` (version 4.1): entity blocks, each listing its node tags, then their coordinates
/// (followed by parametric coordinates if the block says so).
fn read_nodes_v41(
    lines: &mut Lines<'_>,
    section: &Section<'_>,
    table: &mut NodeTable,
) -> Result<(), MshError> {
    let (at, text) = lines.content(section, || "the $Nodes header".into())?;
    let header = at.line;
    let (blocks, total) = block_section_header(at, text, "Nodes")?;
    let mut seen = 0;
    for b in 1..=blocks {
        let (at, text) = lines.content(section, || {
            format!("the header of node block {b} of {blocks}")
        })?;
        let (dim, parametric, count) = block_header(at, text, "parametric")?;
        let parametric = match parametric {
            "0" => false,
            "1" => true,
            other => {
                return Err(at.error(format!(
                    "the parametric flag is {}, not 0 or 1",
                    quote(other)
                )));
            }
        };
        seen = add_to_total(at, seen, count, total, header, "nodes")?;
        for i in 1..=count {
            let (at, text) =
                lines.content(section, || format!("node tag {i} of {count} in block {b}"))?;
            let tokens = split(text);
            let &[tag] = tokens.as_slice() else {
                return Err(at.error(format!(
                    "expected a node tag alone on the line, found {}",
                    quote(text)
                )));
            };
            table.add_tag(at, at.tag(tag, "node tag")?)?;
        }
        // Parametric blocks append u (curves), u v (surfaces) or u v w (volumes) to x y z.
        let width = if parametric { 3 + dim } else { 3 };
        for i in 1..=count {
            let (at, text) = lines.content(section, || {
                format!("the coordinates of node {i} of {count} in block {b}")
            })?;
            let tokens = split(text);
            match tokens.as_slice() {
                &[x, y, z, ..] if tokens.len() == width => table.push_coords(at, [x, y, z])?,
                _ => {
                    return Err(at.error(format!(
                        "a coordinate line of block {b} holds {width} values, this one {}",
                        tokens.len()
                    )));
                }
            }
        }
    }
    if seen != total {
        return Err(lines.at_current().error(format!(
            "the blocks hold {seen} nodes, but {total} were announced at line {header}"
        )));
    }
    lines.end(section, || format!("{total} nodes"))?;
    Ok(())
}

/// `$Elements` (version 4.1): entity blocks of one element type each, `tag nodes…` per line.
fn read_elements_v41<'a>(
    lines: &mut Lines<'a>,
    section: &Section<'_>,
    table: &NodeTable,
) -> Result<Elements<'a>, MshError> {
    let (at, text) = lines.content(section, || "the $Elements header".into())?;
    let header = at.line;
    let (blocks, total) = block_section_header(at, text, "Elements")?;
    let (mut read, mut seen) = (ElementReader::new(table), 0);
    for b in 1..=blocks {
        let (at, text) = lines.content(section, || {
            format!("the header of element block {b} of {blocks}")
        })?;
        let (_, kind, count) = block_header(at, text, "elementType")?;
        let kind = at.int(kind, "element type")?;
        seen = add_to_total(at, seen, count, total, header, "elements")?;
        for i in 1..=count {
            let (at, text) =
                lines.content(section, || format!("element {i} of {count} in block {b}"))?;
            if kept_type(kind).is_none() {
                read.skipped += 1;
                continue;
            }
            let tokens = split(text);
            let [tag, nodes @ ..] = tokens.as_slice() else {
                return Err(at.error("an empty element line"));
            };
            let tag = at.tag(tag, "element tag")?;
            read.add(at, Element { tag, kind, nodes })?;
        }
    }
    if seen != total {
        return Err(lines.at_current().error(format!(
            "the blocks hold {seen} elements, but {total} were announced at line {header}"
        )));
    }
    let end = lines.end(section, || format!("{total} elements"))?;
    Ok(read.finish(end))
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
