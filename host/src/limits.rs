//! The bounds the host holds scenes and scenarios to, checked before anything is allocated or
//! simulated.
//!
//! Every size a user writes (`[capacities]` in `scene.toml`, the mesh cells, frames, features
//! and targets of a `scenario.toml`) has a stated bound here, and the memory the sizes imply
//! together is held to [`MEMORY_BUDGET`]. A value beyond its bound is refused with a message
//! naming the key (and, when the text is at hand, its file and line), before the host asks for
//! the memory: a typo such as `features = 10000000000` is an error, not an aborted process.
//!
//! The bounds are far above every shipped scene (the paper's liver had 438 features and
//! 18 503 pairs; the largest real object, SOFA's fine liver, has 4 293 nodes) and low enough
//! that nothing within them exhausts a workstation.
//!
//! Unknown keys are refused, not warned about: every section of `scene.toml`, `scenario.toml`
//! and a family file denies unknown fields, so that a misspelt key (`cut_vertice = 8`) is an
//! error rather than a default silently used.

use std::fmt;

/// Bytes the host may ask for on behalf of one scene or one scenario: the core's storage of a
/// model, or the generator's frames of the real object. 2 GiB.
pub const MEMORY_BUDGET: usize = 2 << 30;

/// Frames of a scene or a scenario, frame 0 included.
pub const MAX_FRAMES: u64 = 100_000;

/// Tracked features (`[capacities] features`, `[tracking] features`).
pub const MAX_FEATURES: u64 = 65_536;

/// Internal targets (`[capacities] targets`, `[object] targets`).
pub const MAX_TARGETS: u64 = 65_536;

/// Nodes a cut may add (`[capacities] cut_nodes`).
pub const MAX_CUT_NODES: u64 = 1 << 20;

/// Tetrahedra a cut may add (`[capacities] cut_tets`).
pub const MAX_CUT_TETS: u64 = 1 << 22;

/// Entries of the factor (`[capacities] factor_entries`).
pub const MAX_FACTOR_ENTRIES: u64 = 1 << 28;

/// Neighbour pairs of the cut detection (`[capacities] pairs`).
pub const MAX_PAIRS: u64 = 1 << 24;

/// Vertices of the cut line (`[capacities] cut_vertices`).
pub const MAX_CUT_VERTICES: u64 = 65_536;

/// Vertices a cut line needs at least when detection is on: its two ends.
pub const MIN_CUT_VERTICES: u64 = 2;

/// Image width and height, pixels.
pub const MAX_IMAGE_SIDE: u64 = 8_192;

/// Nodes of the generator's real (fine) object.
pub const MAX_FINE_NODES: u64 = 100_000;

/// Nodes of the model mesh a scenario builds.
pub const MAX_MODEL_NODES: u64 = 20_000;

/// Cells of a band or dome along one axis.
pub const MAX_CELLS: u64 = 1_000;

/// Standard deviation of the generator's tracking noise, pixels.
pub const MAX_NOISE_PX: f64 = 1_000.0;

/// Size of an outlier's jump, pixels.
pub const MAX_JUMP_PX: f64 = 10_000.0;

/// A value refused: where it is (`section` empty for a top-level key) and why.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Refusal {
    /// The TOML table (`capacities`, `tracking`, …), empty for a top-level key.
    pub section: &'static str,
    /// The key; empty when the section as a whole is refused (the memory its sizes imply).
    pub key: &'static str,
    /// What is wrong with its value.
    pub message: String,
}

impl Refusal {
    /// A refusal of `section.key`.
    pub fn new(section: &'static str, key: &'static str, message: impl Into<String>) -> Self {
        Refusal {
            section,
            key,
            message: message.into(),
        }
    }

    /// The 1-based line of the key in `text` (the TOML it was read from), or of its section
    /// when the key is absent (its default was refused); 0 if neither is there.
    pub fn line(&self, text: &str) -> usize {
        key_line(text, self.section, self.key)
    }
}

impl fmt::Display for Refusal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.section.is_empty() {
            write!(f, "{}: {}", self.key, self.message)
        } else if self.key.is_empty() {
            write!(f, "[{}]: {}", self.section, self.message)
        } else {
            write!(f, "[{}] {}: {}", self.section, self.key, self.message)
        }
    }
}

impl std::error::Error for Refusal {}

/// Refuses `value` of `section.key` outside `lo..=hi`.
///
/// # Errors
/// A [`Refusal`] naming `section.key` when `value` lies outside the range.
pub fn within(
    section: &'static str,
    key: &'static str,
    value: u64,
    lo: u64,
    hi: u64,
) -> Result<(), Refusal> {
    if value < lo {
        Err(Refusal::new(
            section,
            key,
            format!("{value} is below its least value, {lo}"),
        ))
    } else if value > hi {
        Err(Refusal::new(
            section,
            key,
            format!("{value} is beyond its bound, {hi}"),
        ))
    } else {
        Ok(())
    }
}

/// A `[camera]` picture size: width and height each within 1 ..= [`MAX_IMAGE_SIDE`].
///
/// # Errors
/// A [`Refusal`] naming `camera.width` or `camera.height`.
pub fn image_size(width: u32, height: u32) -> Result<(), Refusal> {
    within("camera", "width", width.into(), 1, MAX_IMAGE_SIDE)?;
    within("camera", "height", height.into(), 1, MAX_IMAGE_SIDE)
}

/// Refuses `value` of `section.key` unless finite and within `lo..=hi`.
///
/// # Errors
/// A [`Refusal`] naming `section.key` when `value` is not finite or lies outside the range.
pub fn within_f64(
    section: &'static str,
    key: &'static str,
    value: f64,
    lo: f64,
    hi: f64,
) -> Result<(), Refusal> {
    if value.is_finite() && value >= lo && value <= hi {
        Ok(())
    } else {
        Err(Refusal::new(
            section,
            key,
            format!("{value} must be a finite number in [{lo}, {hi}]"),
        ))
    }
}

/// Refuses `value` of `section.key` unless finite and positive.
///
/// # Errors
/// A [`Refusal`] naming `section.key` when `value` is zero, negative or not finite.
pub fn positive(section: &'static str, key: &'static str, value: f64) -> Result<(), Refusal> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(Refusal::new(
            section,
            key,
            format!("{value} must be positive and finite"),
        ))
    }
}

/// Refuses a Poisson ratio outside `(-1, 0.5)`.
///
/// # Errors
/// A [`Refusal`] naming `section.key` when `value` lies outside `(-1, 0.5)` or is NaN.
pub fn poisson(section: &'static str, key: &'static str, value: f64) -> Result<(), Refusal> {
    if value > -1.0 && value < 0.5 {
        Ok(())
    } else {
        Err(Refusal::new(
            section,
            key,
            format!("{value} must lie in (-1, 0.5)"),
        ))
    }
}

/// Refuses `bytes` beyond [`MEMORY_BUDGET`]; `what` says what they hold and which keys set
/// them.
///
/// # Errors
/// A [`Refusal`] naming `section.key` when `bytes` exceeds the budget.
pub fn budget(
    section: &'static str,
    key: &'static str,
    bytes: u128,
    what: &str,
) -> Result<(), Refusal> {
    if bytes <= MEMORY_BUDGET as u128 {
        Ok(())
    } else {
        Err(Refusal::new(
            section,
            key,
            format!(
                "{what} would need {}, beyond the host's budget of {}",
                human_bytes(bytes),
                human_bytes(MEMORY_BUDGET as u128)
            ),
        ))
    }
}

/// `bytes` in the largest binary unit that keeps a number of at least 1.
pub fn human_bytes(bytes: u128) -> String {
    const UNITS: [&str; 6] = ["bytes", "KiB", "MiB", "GiB", "TiB", "PiB"];
    let mut value = bytes as f64;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < UNITS.len() {
        value /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{bytes} bytes")
    } else {
        format!("{value:.1} {}", UNITS[unit])
    }
}

/// The 1-based line of `key` in table `section` (dotted for a nested table, empty for the top
/// level) of the TOML `text`, or of the section's header when the key is absent; 0 if the text
/// does not parse or holds neither.
pub fn key_line(text: &str, section: &str, key: &str) -> usize {
    use toml::de::{DeTable, DeValue};
    let Ok(root) = DeTable::parse(text) else {
        return 0;
    };
    let line = |offset: usize| text[..offset.min(text.len())].matches('\n').count() + 1;
    let mut table = root.get_ref();
    let mut table_at = None;
    for part in section.split('.').filter(|p| !p.is_empty()) {
        let Some((k, v)) = table.iter().find(|(k, _)| k.get_ref().as_ref() == part) else {
            return 0;
        };
        let DeValue::Table(t) = v.get_ref() else {
            return 0;
        };
        table = t;
        table_at = Some(k.span().start);
    }
    match table.iter().find(|(k, _)| k.get_ref().as_ref() == key) {
        Some((k, _)) => line(k.span().start),
        None => table_at.map_or(0, line),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn key_line_finds_keys_and_sections() {
        let text = "name = \"x\"\nframes = 3\n\n[capacities]\nfeatures = 9\n\n[a.b]\nc = 1\n";
        assert_eq!(key_line(text, "", "frames"), 2);
        assert_eq!(key_line(text, "capacities", "features"), 5);
        // An absent key: its section's header.
        assert_eq!(key_line(text, "capacities", "pairs"), 4);
        assert_eq!(key_line(text, "a.b", "c"), 8);
        assert_eq!(key_line(text, "nothing", "c"), 0);
        assert_eq!(key_line("not toml [", "", "x"), 0);
    }

    #[test]
    fn refusals_name_the_key() {
        let r = within("capacities", "features", 10_000_000_000, 1, MAX_FEATURES).unwrap_err();
        assert_eq!(
            r.to_string(),
            "[capacities] features: 10000000000 is beyond its bound, 65536"
        );
        let r = within_f64("tracking", "noise_px", f64::NAN, 0.0, 1.0).unwrap_err();
        assert!(r.to_string().starts_with("[tracking] noise_px: NaN"), "{r}");
        assert!(within("", "frames", 0, 2, MAX_FRAMES).is_err());
        assert!(budget("", "frames", 3 << 30, "positions").is_err());
        assert!(budget("", "frames", 1 << 30, "positions").is_ok());
        assert_eq!(human_bytes(3 << 30), "3.0 GiB");
    }
}
