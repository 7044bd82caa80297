//! Reading a Gmsh file one line at a time: every Gmsh ASCII layout puts one node, one element
//! or one block header per line, so lines (not a token stream) are the unit, and a truncated
//! section is found at its end marker instead of reading on into the next section. Also the
//! `$MeshFormat` section, which says which version the rest is in.

use super::{MshError, MshVersion};

/// A place in the file, for errors.
#[derive(Clone, Copy)]
pub(super) struct At<'a> {
    file: &'a str,
    pub(super) line: usize,
}

impl At<'_> {
    pub(super) fn error(self, message: impl Into<String>) -> MshError {
        MshError {
            file: self.file.to_owned(),
            line: self.line,
            message: message.into(),
        }
    }

    /// A count or index (`usize`).
    pub(super) fn count(self, token: &str, what: &str) -> Result<usize, MshError> {
        token.parse().map_err(|_| {
            self.error(format!(
                "the {what} is {}, not a non-negative integer",
                quote(token)
            ))
        })
    }

    /// A node or element tag (`u64`).
    pub(super) fn tag(self, token: &str, what: &str) -> Result<u64, MshError> {
        token.parse().map_err(|_| {
            self.error(format!(
                "the {what} is {}, not a non-negative integer",
                quote(token)
            ))
        })
    }

    /// A signed integer whose value does not matter (entity tags); checked so that a corrupt
    /// line is noticed.
    pub(super) fn int(self, token: &str, what: &str) -> Result<i64, MshError> {
        token
            .parse()
            .map_err(|_| self.error(format!("the {what} is {}, not an integer", quote(token))))
    }

    /// The three coordinates of a node, finite.
    pub(super) fn coords(self, tokens: [&str; 3], tag: Option<u64>) -> Result<[f64; 3], MshError> {
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
pub(super) fn quote(text: &str) -> String {
    const MAX: usize = 40;
    match text.char_indices().nth(MAX) {
        Some((cut, _)) => format!("{:?}…", &text[..cut]),
        None => format!("{text:?}"),
    }
}

/// A section being read: its name without `$` and the line of its header.
pub(super) struct Section<'a> {
    pub(super) name: &'a str,
    pub(super) line: usize,
}

impl Section<'_> {
    pub(super) fn is_end(&self, text: &str) -> bool {
        // Version 1 writes `$ENDNOD`, later versions `$EndNodes`.
        text.strip_prefix("$End")
            .or_else(|| text.strip_prefix("$END"))
            .or_else(|| text.strip_prefix("$end"))
            .is_some_and(|rest| rest.eq_ignore_ascii_case(self.name))
    }
}

/// The non-blank lines of the file, trimmed, with their 1-based numbers.
pub(super) struct Lines<'a> {
    file: &'a str,
    iter: std::iter::Enumerate<std::str::Lines<'a>>,
    /// The number of the file's last line (1 for an empty file), where a truncation is reported.
    last_line: usize,
    /// The number of the line returned last (0 before the first).
    current: usize,
}

impl<'a> Lines<'a> {
    pub(super) fn new(text: &'a str, file: &'a str) -> Self {
        Lines {
            file,
            iter: text.lines().enumerate(),
            last_line: text.lines().count().max(1),
            current: 0,
        }
    }

    pub(super) fn next_line(&mut self) -> Option<(At<'a>, &'a str)> {
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

    pub(super) fn at_end(&self) -> At<'a> {
        At {
            file: self.file,
            line: self.last_line,
        }
    }

    pub(super) fn at_current(&self) -> At<'a> {
        At {
            file: self.file,
            line: self.current.max(1),
        }
    }

    /// The next content line of `section`; `expecting` says what it should hold, for the error
    /// when the section or the file ends first.
    pub(super) fn content(
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
    pub(super) fn end(
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
    pub(super) fn skip_section(&mut self, section: &Section<'_>) -> Result<(), MshError> {
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
pub(super) fn read_mesh_format(lines: &mut Lines<'_>) -> Result<MshVersion, MshError> {
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
