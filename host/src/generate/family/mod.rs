//! Scene families: many variants of one base scenario, drawn at random within ranges, on
//! which cut detection is judged with its default settings (`incise gen --family`).
//!
//! A family file (TOML) names a base `scenario.toml` and, for each thing that varies, a range
//! `[low, high]` from which every variant draws uniformly with the project's seeded
//! [`Rng`]. Every field is described on [`Family`]. Example:
//!
//! ```toml
//! name = "band"
//! base = "../band-side-cut/scenario.toml"   # relative to this file
//! variants = 20
//! seed = 1
//! intact_fraction = 0.5        # variants without a slit (they must stay uncut)
//! intact_pull = 1.0            # how much of the base's grasp motion the intact ones make
//! live_fraction = 0.3          # cut variants whose cut grows while filmed
//! noise_px = [0.3, 2.0]
//! dropout = [0.0, 0.10]
//! outlier_fraction = [0.0, 0.10]
//! pull_frames = [5, 25]
//! oblique_degrees = [0.0, 40.0]
//! cut_shift = [-0.2, 0.2]
//! cut_length = [0.5, 0.9]
//! ```
//!
//! Variant `i` is named `<name>-<i>` (two digits at least) and draws from its own stream,
//! seeded by the family's seed and `i` alone, so its draws do not depend on how many
//! variants there are. Which variants are intact, pre-cut or live is not drawn per variant
//! but dealt: the counts are the fractions rounded (`intact_fraction` of `variants`,
//! `live_fraction` of the rest), and a shuffle seeded by the family's seed places them.
//!
//! Each variant is checked before it is accepted, and drawn again (from the same stream, at
//! most [`MAX_DRAWS`] times) if it fails: the real object and its slit must build (the slit
//! still cuts the object, held and grasped boxes still hold nodes), at most a tenth of the
//! slit's node pairs may lie in a held or grasped box (pinned shut), the camera must still
//! see at least half as many pixels of the object at rest as the base camera does, and the
//! slit's line must be in view (at least two of its lips visible in the image at rest).
//!
//! Here: the family file and drawing its variants ([`variants`], [`generate_family`]);
//! `variant`: one variant's draws, how it is derived from the base scenario, and its checks.

use std::path::{Path, PathBuf};

use indicatif::{ProgressBar, ProgressStyle};
use serde::{Deserialize, Serialize};

use crate::generate::live::extent;
use crate::generate::pipeline::{
    GenError, Generated, ModelMesh, generate_scenario, object_meshes, spec_camera,
};
use crate::generate::scenario::Scenario;
use crate::render::silhouette;
use crate::rng::Rng;
use crate::scene::SceneError;

mod variant;

use variant::{BaseGeometry, Draws, derive, first_start, sensible};

/// Most draws of one variant before [`variants`] gives up on it.
pub const MAX_DRAWS: usize = 16;

/// A family file. Ranges are `[low, high]` (inclusive for `pull_frames`); a range left out
/// keeps the base scenario's value.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Family {
    /// Family name: letters, digits, `-` and `_`; variant `i` is `<name>-<i>`.
    pub name: String,
    /// One line on what the family varies.
    #[serde(default)]
    pub description: String,
    /// The base scenario file, relative to the family file. Its mesh paths stay relative to
    /// its own directory.
    pub base: String,
    /// How many variants (1 to 1000).
    pub variants: usize,
    /// Seed of every draw.
    pub seed: u64,
    /// Share of the variants without a slit, in `[0, 1]`: controls on which nothing may be
    /// cut. Needs a base with a `[slit]` when below 1.
    #[serde(default)]
    pub intact_fraction: f64,
    /// Share of the cut variants whose cut grows while filmed (a live cut, `[slit] grow`), in
    /// `[0, 1]`. The rest are pre-cut.
    #[serde(default)]
    pub live_fraction: f64,
    /// The intact variants' grasps move this fraction of the base's motion (displacement and
    /// rotation), in `(0, 1]` (1, the whole motion, when left out). A base whose grasps pull the two sides of its
    /// slit apart opens the slit with that motion; without the slit the same motion stretches
    /// the tissue between the grasps instead, and may stretch it far beyond what intact tissue
    /// bears (the liver's: 175 %). Such a control is a tear, not an intact organ.
    #[serde(default = "whole_pull")]
    pub intact_pull: f64,
    /// `[tracking] noise_px`: the trackers' Gaussian noise, pixels (≥ 0).
    #[serde(default)]
    pub noise_px: Option<[f64; 2]>,
    /// `[tracking] dropout`: probability that a feature is lost in a frame, in `[0, 1)`.
    #[serde(default)]
    pub dropout: Option<[f64; 2]>,
    /// `[tracking] outlier_fraction`: share of features that jump, in `[0, 1]`.
    #[serde(default)]
    pub outlier_fraction: Option<[f64; 2]>,
    /// Frames of a full pull: the grasps' motions, from the first start to the last end, are
    /// retimed (scaled about the first start, rounded to frames) to last this many frames, a
    /// whole number drawn in the range (≥ 1). The number of frames stays the base's, so a
    /// shorter pull ends earlier and holds longer. The first start plus the longest pull must
    /// stay below `frames`.
    #[serde(default)]
    pub pull_frames: Option<[u32; 2]>,
    /// The camera turned about the point it looks at by this angle, degrees in `[0, 80]`,
    /// about an axis across the view in a direction of the image drawn uniformly (its up
    /// vector turns with it). An image slit is pinned to the base camera (`[slit.camera]`),
    /// so the cut stays where it was on the object.
    #[serde(default)]
    pub oblique_degrees: Option<[f64; 2]>,
    /// The slit moved across itself, as a fraction of the object's size across the cut, in
    /// `[−0.5, 0.5]`: a plane slit along its normal by that fraction of the object's extent
    /// along the normal (its `point` and `region` move together); an image slit perpendicular
    /// to its segment by that fraction of the object's extent across the segment in the image
    /// (seen at rest through the slit's camera). Held and grasped boxes do not move.
    #[serde(default)]
    pub cut_shift: Option<[f64; 2]>,
    /// The slit's length as a fraction of the base slit's, in `(0, 1]`, measured from where
    /// it enters the object: a plane slit that starts at the object's boundary keeps that end
    /// and moves the other side of its region; one across the middle shrinks about its centre
    /// (along the in-plane axis its region is longest); an image slit keeps its first end
    /// and moves its second toward the point where the segment enters the object's rest
    /// silhouette.
    #[serde(default)]
    pub cut_length: Option<[f64; 2]>,
    /// Changes to the base scenario before anything is drawn: a table merged key by key into
    /// it, e.g. `[override.object]` with `real_mesh = ""` (the real liver made from the model
    /// refined instead of its own fine mesh).
    #[serde(default, rename = "override")]
    pub overrides: toml::Table,
}

/// [`Family::intact_pull`] left out: the base's whole motion.
fn whole_pull() -> f64 {
    1.0
}

/// What a variant is (`intact`, `pre-cut` or `live` when written out).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Kind {
    /// No slit.
    Intact,
    /// The base's slit (moved and shortened), there from frame 0.
    PreCut,
    /// The same, cut while filmed.
    Live,
}

impl Kind {
    /// The name `incise eval` prints: `intact`, `pre-cut` or `live`.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Intact => "intact",
            Kind::PreCut => "pre-cut",
            Kind::Live => "live",
        }
    }
}

impl Family {
    /// Reads and checks a family file.
    ///
    /// # Errors
    /// A [`SceneError`] naming the file and the line.
    pub fn load(path: &Path) -> Result<Family, SceneError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| SceneError::new(path, 0, format!("cannot read: {e}")))?;
        let family: Family = toml::from_str(&text).map_err(|e| {
            let line = e
                .span()
                .map_or(0, |s| line_at(&text, s.start.min(text.len())));
            SceneError::new(path, line, e.message().to_string())
        })?;
        family
            .check()
            .map_err(|(key, message)| SceneError::new(path, key_line(&text, key), message))?;
        Ok(family)
    }

    /// Checks the values; on failure the key at fault and what is wrong.
    fn check(&self) -> Result<(), (&'static str, String)> {
        let bad = |key: &'static str, m: String| Err((key, format!("{key}: {m}")));
        if self.name.is_empty()
            || !self
                .name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
        {
            return bad(
                "name",
                format!(
                    "{:?} must be letters, digits, - and _ (it names directories)",
                    self.name
                ),
            );
        }
        if !(1..=1000).contains(&self.variants) {
            return bad("variants", format!("{} is not in 1..=1000", self.variants));
        }
        for (key, f) in [
            ("intact_fraction", self.intact_fraction),
            ("live_fraction", self.live_fraction),
        ] {
            if !(0.0..=1.0).contains(&f) {
                return bad(key, format!("{f} is not in [0, 1]"));
            }
        }
        let f = self.intact_pull;
        if !(f > 0.0 && f <= 1.0) {
            return bad("intact_pull", format!("{f} is not in (0, 1]"));
        }
        let ranges = [
            ("noise_px", self.noise_px, 0.0, f64::INFINITY, false),
            ("dropout", self.dropout, 0.0, 1.0, true),
            ("outlier_fraction", self.outlier_fraction, 0.0, 1.0, false),
            ("oblique_degrees", self.oblique_degrees, 0.0, 80.0, false),
            ("cut_shift", self.cut_shift, -0.5, 0.5, false),
            ("cut_length", self.cut_length, 0.0, 1.0, false),
        ];
        for (key, range, lo, hi, open_high) in ranges {
            let Some([a, b]) = range else { continue };
            if !(a.is_finite() && b.is_finite() && a <= b) {
                return bad(key, format!("[{a}, {b}] is not a range [low, high]"));
            }
            let above = if open_high { b >= hi } else { b > hi };
            if a < lo || above || (key == "cut_length" && a <= 0.0) {
                let low = if key == "cut_length" { "(" } else { "[" };
                let high = if open_high { ")" } else { "]" };
                return bad(
                    key,
                    format!("[{a}, {b}] is not within {low}{lo}, {hi}{high}"),
                );
            }
        }
        if let Some([a, b]) = self.pull_frames
            && (a == 0 || a > b)
        {
            return bad(
                "pull_frames",
                format!("[{a}, {b}] is not a range of at least one frame"),
            );
        }
        Ok(())
    }

    /// The base scenario's path: `base` relative to the family file's directory.
    pub fn base_path(&self, family_path: &Path) -> PathBuf {
        family_path
            .parent()
            .unwrap_or(Path::new("."))
            .join(&self.base)
    }

    /// The directory the variants' mesh paths are relative to: the base scenario's.
    pub fn base_dir(&self, family_path: &Path) -> PathBuf {
        self.base_path(family_path)
            .parent()
            .map_or_else(|| PathBuf::from("."), Path::to_path_buf)
    }

    /// The base scenario with the family's `[override]` merged in.
    ///
    /// # Errors
    /// A [`GenError`] naming the base file (and its line) or the override at fault.
    pub fn base_scenario(&self, family_path: &Path) -> Result<Scenario, GenError> {
        let path = self.base_path(family_path);
        let base = Scenario::load(&path).map_err(|e| GenError(e.to_string()))?;
        if self.overrides.is_empty() {
            return Ok(base);
        }
        let text = std::fs::read_to_string(&path)
            .map_err(|e| GenError(format!("{}: cannot read: {e}", path.display())))?;
        let mut table: toml::Table = toml::from_str(&text)
            .map_err(|e| GenError(format!("{}: {}", path.display(), e.message())))?;
        merge(&mut table, &self.overrides);
        toml::Value::Table(table)
            .try_into()
            .map_err(|e: toml::de::Error| {
                GenError(format!(
                    "{}: [override] on {}: {}",
                    family_path.display(),
                    path.display(),
                    e.message()
                ))
            })
    }

    /// The name of variant `index`: `<name>-<index>`, the index zero-padded to at least two
    /// digits (to as many as the last index has).
    pub fn variant_name(&self, index: usize) -> String {
        let width = self.variants.saturating_sub(1).to_string().len().max(2);
        format!("{}-{index:0width$}", self.name)
    }

    /// The kind of every variant: the counts are `intact_fraction` of `variants` and
    /// `live_fraction` of the rest, rounded; a seeded shuffle places them.
    pub fn kinds(&self) -> Vec<Kind> {
        let n = self.variants;
        let intact = ((n as f64) * self.intact_fraction).round() as usize;
        let live = (((n - intact.min(n)) as f64) * self.live_fraction).round() as usize;
        let mut kinds: Vec<Kind> = (0..n)
            .map(|i| {
                if i < intact {
                    Kind::Intact
                } else if i < intact + live {
                    Kind::Live
                } else {
                    Kind::PreCut
                }
            })
            .collect();
        let mut rng = Rng::new(self.seed);
        for i in (1..n).rev() {
            let j = (rng.next_u64() % (i as u64 + 1)) as usize;
            kinds.swap(i, j);
        }
        kinds
    }
}

/// 1-based line of byte `offset` in `text`.
fn line_at(text: &str, offset: usize) -> usize {
    text[..offset].matches('\n').count() + 1
}

/// 1-based line where `key = …` is set at the top of a TOML text, 0 if it is not.
fn key_line(text: &str, key: &str) -> usize {
    text.lines()
        .position(|l| {
            l.trim_start()
                .strip_prefix(key)
                .is_some_and(|rest| rest.trim_start().starts_with('='))
        })
        .map_or(0, |i| i + 1)
}

/// Merges `over` into `into`: tables key by key, anything else replaced.
fn merge(into: &mut toml::Table, over: &toml::Table) {
    for (k, v) in over {
        match (into.get_mut(k), v) {
            (Some(toml::Value::Table(a)), toml::Value::Table(b)) => merge(a, b),
            _ => {
                into.insert(k.clone(), v.clone());
            }
        }
    }
}

/// The variants of a family, drawn as [`Family`] describes; `family_path` is the family
/// file (the base is relative to it). Their mesh paths are relative to
/// [`Family::base_dir`].
///
/// # Errors
/// A [`GenError`] for a family that does not fit its base (cut variants of a base without a
/// slit, a pull longer than the frames allow, a slit whose length axis cannot be told) or a
/// variant that fails its checks [`MAX_DRAWS`] times in a row (the message says which check).
pub fn variants(family: &Family, family_path: &Path) -> Result<Vec<Scenario>, GenError> {
    let at = |m: String| GenError(format!("{}: {m}", family_path.display()));
    family.check().map_err(|(_, m)| at(m))?;
    let base = family.base_scenario(family_path)?;
    let base_dir = family.base_dir(family_path);
    let kinds = family.kinds();
    if base.slit.is_none() && kinds.iter().any(|&k| k != Kind::Intact) {
        return Err(at(format!(
            "the base {} has no [slit]: only intact variants (intact_fraction = 1) can be made",
            family.base
        )));
    }
    if let Some([_, longest]) = family.pull_frames {
        let first = first_start(&base)
            .ok_or_else(|| at("pull_frames: the base has no [[motion.grasp]]".into()))?;
        if first + longest >= base.frames {
            return Err(at(format!(
                "pull_frames: a pull of {longest} frames from frame {first} ends after the \
                 last frame ({})",
                base.frames - 1
            )));
        }
    }
    let (model, real, _) = object_meshes(&base, &base_dir)?;
    let model_triangles: Vec<[u32; 3]> = model.boundary().iter().map(|b| b.0).collect();
    let base_camera = spec_camera(&base.camera)?;
    let geometry = BaseGeometry {
        seen: silhouette(&base_camera, &model.nodes, &model_triangles).count(),
        model_nodes: model.nodes,
        model_triangles,
        real_extent: extent(&real.nodes),
    };

    let mut out = Vec::with_capacity(family.variants);
    for (index, &kind) in kinds.iter().enumerate() {
        let mut rng = Rng::new(
            family
                .seed
                .wrapping_add((index as u64 + 1).wrapping_mul(0xD1B5_4A32_D192_ED03)),
        );
        let mut failure = String::new();
        let mut accepted = None;
        for _ in 0..MAX_DRAWS {
            let d = Draws::take(&mut rng);
            let v = derive(family, &base, &geometry, index, kind, &d).map_err(&at)?;
            match sensible(&v, &base_dir, &geometry) {
                Ok(()) => {
                    accepted = Some(v);
                    break;
                }
                Err(e) => failure = e,
            }
        }
        match accepted {
            Some(v) => out.push(v),
            None => {
                return Err(at(format!(
                    "{}: no sensible variant in {MAX_DRAWS} draws; the last: {failure}",
                    family.variant_name(index)
                )));
            }
        }
    }
    Ok(out)
}

/// Generates every variant of the family at `family_path` into `out/<variant name>/`
/// (`scenario.toml` and the scene, see [`generate_scenario`]), with a progress bar over the
/// variants when `progress`.
///
/// # Errors
/// A [`GenError`] from [`Family::load`], [`variants`] or the generation of a variant (named).
pub fn generate_family(
    family_path: &Path,
    out: &Path,
    progress: bool,
) -> Result<Vec<Generated>, GenError> {
    let family = Family::load(family_path).map_err(|e| GenError(e.to_string()))?;
    let scenarios = variants(&family, family_path)?;
    let base_dir = family.base_dir(family_path);
    std::fs::create_dir_all(out).map_err(|e| GenError(format!("{}: {e}", out.display())))?;
    let bar = if progress {
        let b = ProgressBar::new(scenarios.len() as u64);
        b.set_style(
            ProgressStyle::with_template("{prefix:>16} [{bar:30}] {pos}/{len} variants {msg}")
                .map_err(|e| GenError(e.to_string()))?
                .progress_chars("=> "),
        );
        b.set_prefix(family.name.clone());
        b
    } else {
        ProgressBar::hidden()
    };
    let mut done = Vec::with_capacity(scenarios.len());
    // Without a terminal the bar draws nothing: a line per variant says where a long run is.
    let plain = progress && !std::io::IsTerminal::is_terminal(&std::io::stderr());
    for (k, s) in scenarios.iter().enumerate() {
        if plain {
            eprintln!(
                "{}: {} ({}/{})",
                family.name,
                s.name,
                k + 1,
                scenarios.len()
            );
        }
        bar.set_message(s.name.clone());
        let g = generate_scenario(s, &base_dir, &out.join(&s.name), ModelMesh::Scenario, false)
            .map_err(|e| GenError(format!("{}: {e}", s.name)))?;
        done.push(g);
        bar.inc(1);
    }
    bar.finish_and_clear();
    Ok(done)
}

#[cfg(test)]
mod tests {
    use incise_core::nalgebra::Vector3;

    use super::*;
    use crate::generate::pipeline::prepare_scenario;
    use crate::generate::scenario::CameraSpec;

    fn fixtures() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures")
    }

    fn within(x: f64, r: [f64; 2]) -> bool {
        x >= r[0] - 1e-12 && x <= r[1] + 1e-12
    }

    #[test]
    fn band_variants_are_deterministic_within_their_ranges_and_dealt_by_share() {
        let path = fixtures().join("families/band.toml");
        let family = Family::load(&path).unwrap();
        let base = family.base_scenario(&path).unwrap();
        let a = variants(&family, &path).unwrap();
        assert_eq!(a, variants(&family, &path).unwrap());
        assert_eq!(a.len(), 20);
        // Shares: half intact; of the ten cut ones, three live.
        assert_eq!(a.iter().filter(|v| v.slit.is_none()).count(), 10);
        let live = a
            .iter()
            .filter(|v| v.slit.as_ref().is_some_and(|s| s.grow.is_some()))
            .count();
        assert_eq!(live, 3);
        let kinds = family.kinds();
        for (v, k) in a.iter().zip(&kinds) {
            let grows = v.slit.as_ref().map(|s| s.grow.is_some());
            let want = match k {
                Kind::Intact => None,
                Kind::PreCut => Some(false),
                Kind::Live => Some(true),
            };
            assert_eq!(grows, want, "{}", v.name);
        }
        let mut seeds: Vec<u64> = a.iter().map(|v| v.seed).collect();
        seeds.sort_unstable();
        seeds.dedup();
        assert_eq!(seeds.len(), 20);

        let view = |c: &CameraSpec| Vector3::from(c.eye) - Vector3::from(c.target);
        let base_slit = base.slit.as_ref().unwrap();
        let (base_x, base_y) = (base_slit.point.unwrap()[0], base_slit.region.unwrap()[1][1]);
        for (i, v) in a.iter().enumerate() {
            assert_eq!(v.name, format!("band-{i:02}"));
            assert_eq!(v.frames, base.frames);
            assert_eq!(v.object, base.object);
            assert_eq!(v.motion.held, base.motion.held);
            let (g, bg) = (&v.motion.grasp[0], &base.motion.grasp[0]);
            assert_eq!(
                (g.region, g.displacement, g.start),
                (bg.region, bg.displacement, 3)
            );
            assert!((5..=25).contains(&(g.end - g.start)), "{}", v.name);
            assert!(within(v.tracking.noise_px, [0.3, 2.0]));
            assert!(within(v.tracking.dropout, [0.0, 0.1]));
            assert!(within(v.tracking.outlier_fraction, [0.0, 0.1]));
            // The camera turned about its target: same target and distance, the view
            // direction at most 40° off the base's, the up vector turned with it.
            let (d, bd) = (view(&v.camera), view(&base.camera));
            assert_eq!(v.camera.target, base.camera.target);
            assert!((d.norm() - bd.norm()).abs() < 1e-12);
            let angle = d.angle(&bd).to_degrees();
            assert!(within(angle, [0.0, 40.0]), "{angle}");
            let up = Vector3::from(v.camera.up);
            assert!((up.dot(&d) - Vector3::from(base.camera.up).dot(&bd)).abs() < 1e-12);
            let Some(sl) = &v.slit else { continue };
            // Shifted along x by at most a fifth of the band's length, its region with it;
            // shortened to 50–90% of the base slit's reach across the band from y = 0.
            let (x, region) = (sl.point.unwrap()[0], sl.region.unwrap());
            assert!(within(x - base_x, [-0.02, 0.02]), "{x}");
            assert!((region[0][0] - (x - 0.005)).abs() < 1e-12);
            assert!(within(region[1][1] / base_y, [0.5, 0.9]));
            assert_eq!(region[0][1], base_slit.region.unwrap()[0][1]);
            if let Some([start, end]) = sl.grow {
                assert!(
                    g.start <= start && start < end && end <= g.end,
                    "{:?}",
                    sl.grow
                );
            }
            // What is written reads back the same.
            let text = v.to_toml().unwrap();
            assert_eq!(&Scenario::parse(&text, Path::new("x")).unwrap(), v);
        }

        // A variant draws the same values however many variants there are (its kind is
        // dealt and may change).
        let few = Family {
            variants: 5,
            ..family.clone()
        };
        for (x, y) in variants(&few, &path).unwrap().iter().zip(&a) {
            assert_eq!(
                (x.seed, &x.tracking, &x.camera),
                (y.seed, &y.tracking, &y.camera)
            );
        }
    }

    #[test]
    fn intact_pull_scales_only_the_intact_variants_grasps() {
        let path = fixtures().join("families/band.toml");
        let whole = Family {
            intact_pull: 1.0,
            ..Family::load(&path).unwrap()
        };
        let quarter = Family {
            intact_pull: 0.25,
            ..whole.clone()
        };
        let (a, b) = (
            variants(&whole, &path).unwrap(),
            variants(&quarter, &path).unwrap(),
        );
        let kinds = whole.kinds();
        assert!(kinds.contains(&Kind::Intact) && kinds.contains(&Kind::PreCut));
        for ((x, y), kind) in a.iter().zip(&b).zip(&kinds) {
            // The same draws either way: only an intact variant's grasps differ.
            assert_eq!(
                (x.seed, &x.tracking, &x.camera),
                (y.seed, &y.tracking, &y.camera)
            );
            if *kind != Kind::Intact {
                assert_eq!(x, y);
                continue;
            }
            assert!(
                y.description.contains("grasps moved ×0.25"),
                "{}",
                y.description
            );
            for (g, h) in x.motion.grasp.iter().zip(&y.motion.grasp) {
                for (p, q) in g.displacement.iter().zip(&h.displacement) {
                    assert!((q - 0.25 * p).abs() < 1e-15, "{p} {q}");
                }
                assert!((h.rotation_degrees - 0.25 * g.rotation_degrees).abs() < 1e-12);
                assert_eq!((g.region, g.start, g.end), (h.region, h.start, h.end));
            }
        }
    }

    #[test]
    fn dome_and_liver_families_make_sensible_variants() {
        for name in ["dome", "liver"] {
            let path = fixtures().join(format!("families/{name}.toml"));
            let family = Family::load(&path).unwrap();
            let v = variants(&family, &path).unwrap();
            assert_eq!(v.len(), family.variants);
            assert_eq!(v.iter().filter(|s| s.slit.is_none()).count(), 10, "{name}");
            // Every variant builds, and its slit cuts the object.
            for s in &v {
                let p = prepare_scenario(s.clone(), &family.base_dir(&path)).unwrap();
                assert_eq!(p.meshes.lips.is_empty(), s.slit.is_none(), "{}", s.name);
            }
        }
        // The liver family's real object is the model refined, not SOFA's fine liver.
        let path = fixtures().join("families/liver.toml");
        let family = Family::load(&path).unwrap();
        assert_eq!(family.base_scenario(&path).unwrap().object.real_mesh, "");
    }

    #[test]
    fn family_errors_name_the_file_and_line() {
        let dir = tempfile::tempdir().unwrap();
        let base = fixtures().join("band-side-cut/scenario.toml");
        let write = |body: &str| {
            let path = dir.path().join("family.toml");
            std::fs::write(
                &path,
                format!(
                    "name = \"f\"\nbase = {:?}\nvariants = 4\nseed = 1\n{body}",
                    base.display().to_string()
                ),
            )
            .unwrap();
            path
        };
        let e = Family::load(&write("noise = [0.1, 0.2]\n")).unwrap_err();
        assert_eq!(e.line, 5, "{e}");
        let e = Family::load(&write("intact_fraction = 0.5\ndropout = [0.2, 0.1]\n")).unwrap_err();
        assert_eq!(e.line, 6, "{e}");
        assert!(e.message.contains("dropout"), "{e}");
        for bad in ["0.0", "1.5", "nan"] {
            let e = Family::load(&write(&format!("intact_pull = {bad}\n"))).unwrap_err();
            assert!(e.message.contains("intact_pull"), "{e}");
            assert_eq!(e.line, 5, "{e}");
        }
        let e = Family::load(&write("name2 = 1\n")).unwrap_err();
        assert_eq!(e.line, 5, "{e}");
        // Too long a pull for the base's frames (the grasp starts at frame 3 of 40).
        let path = write("pull_frames = [5, 37]\n");
        let e = variants(&Family::load(&path).unwrap(), &path).unwrap_err();
        assert!(e.0.contains("pull_frames"), "{e}");
        // Cut variants of a base without a slit.
        let path = dir.path().join("nocut.toml");
        std::fs::write(
            &path,
            format!(
                "name = \"f\"\nbase = {:?}\nvariants = 4\nseed = 1\n",
                fixtures()
                    .join("band-no-cut/scenario.toml")
                    .display()
                    .to_string()
            ),
        )
        .unwrap();
        let e = variants(&Family::load(&path).unwrap(), &path).unwrap_err();
        assert!(e.0.contains("no [slit]"), "{e}");
        // A bad override names the family file.
        let path = write("[override.object]\nshape = 3\n");
        let e = variants(&Family::load(&path).unwrap(), &path).unwrap_err();
        assert!(e.0.contains("[override]"), "{e}");
    }
}
