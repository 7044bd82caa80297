//! The `$Nodes` and `$Elements` sections of every version: the node table, the one table of
//! element types kept, and the per-version layouts of a node or element line.

use std::collections::HashMap;
use std::collections::hash_map::Entry;

use super::lines::{At, Lines, Section, quote};
use super::{MshError, MshVersion};

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
pub(super) const TET4: i64 = KEPT[0].number;

/// The entry of [`KEPT`] for element type `number`, if elements of it are kept.
fn kept_type(number: i64) -> Option<&'static ElementType> {
    KEPT.iter().find(|t| t.number == number)
}

/// The nodes read so far, renumbered in order of appearance.
#[derive(Default)]
pub(super) struct NodeTable {
    pub(super) coords: Vec<[f64; 3]>,
    pub(super) tags: Vec<u64>,
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
pub(super) struct Elements<'a> {
    pub(super) tets: Vec<[u32; 4]>,
    pub(super) skipped: usize,
    /// The end marker, where "no tetrahedron" is reported.
    pub(super) end: At<'a>,
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

/// Reads the nodes section of a `version` file (`$NOD` or `$Nodes`) into `table`.
pub(super) fn read_nodes(
    version: MshVersion,
    lines: &mut Lines<'_>,
    section: &Section<'_>,
    table: &mut NodeTable,
) -> Result<(), MshError> {
    match version {
        MshVersion::V4_1 => read_nodes_v41(lines, section, table),
        MshVersion::V1 | MshVersion::V2_2 => read_nodes_v12(lines, section, table),
    }
}

/// Reads the elements section of a `version` file (`$ELM` or `$Elements`), its node tags
/// looked up in `table`.
pub(super) fn read_elements<'a>(
    version: MshVersion,
    lines: &mut Lines<'a>,
    section: &Section<'_>,
    table: &NodeTable,
) -> Result<Elements<'a>, MshError> {
    match version {
        MshVersion::V1 => read_counted_elements(lines, section, table, element_v1),
        MshVersion::V2_2 => read_counted_elements(lines, section, table, element_v2),
        MshVersion::V4_1 => read_elements_v41(lines, section, table),
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
fn read_counted_elements<'a>(
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
