//! The overlay picture of one frame: what the model and the detector make of it, over the
//! video picture (or, for a synthetic scene, over the true silhouette), with a title and a
//! legend so that it reads on its own.

use image::RgbImage;
use incise_core::{Camera, Observation};
use nalgebra::Vector3;

use super::{Canvas, Corner, Mask, colour};
use crate::metrics::DirectedHausdorff;

/// Everything one frame's overlay shows.
pub struct Overlay<'a> {
    /// Scene name (title).
    pub scene: &'a str,
    /// Frame number (title).
    pub frame: usize,
    /// The scene's camera.
    pub camera: &'a Camera<f64>,
    /// The video picture, if there is one; otherwise the true silhouette is the background.
    pub picture: Option<&'a RgbImage>,
    /// The model's virtual features projected into the image, pixels.
    pub virtual_features: &'a [[f64; 2]],
    /// The detector's separation points of the frame, pixels.
    pub separation_points: &'a [[f64; 2]],
    /// The detector's evidence, if asked for: the neighbour pairs that are outliers in the
    /// frame and those counted as split, as segments between their features, pixels.
    pub pairs: Option<&'a DetectorPairs>,
    /// The model's node positions and boundary triangles (copied out of the model by the caller, who
    /// also measures with them).
    pub positions: &'a [[f64; 3]],
    /// Boundary triangles of the model.
    pub surface: &'a [[u32; 3]],
    /// The model's silhouette.
    pub model_mask: &'a Mask,
    /// The true silhouette, with a ground truth.
    pub truth_mask: Option<&'a Mask>,
    /// The true cut in the image, with a ground truth.
    pub true_cut: Option<&'a [Vec<[f64; 2]>]>,
    /// The frame's tracked features.
    pub observations: &'a [Observation<f64>],
    /// The tracked positions this frame of the features the temporal filter has taken out
    /// (as tracking failures), pixels.
    pub filtered: &'a [[f64; 2]],
    /// The detected cut line, pixels.
    pub cut_line: &'a [[f64; 2]],
    /// Its distance to the true cut in the frame, with where each half is attained (the
    /// line's point farthest from the cut, the cut's farthest from the line): drawn as a ring
    /// at each with a stroke to the nearest point across, so that a picture shows where the
    /// Hausdorff distance comes from.
    pub farthest: Option<DirectedHausdorff>,
    /// The internal targets where the model carries them.
    pub targets: &'a [[f64; 3]],
    /// Dice of the frame (NaN without a ground truth).
    pub dice: f64,
    /// Target error of the frame, millimetres (NaN without a ground truth).
    pub target_error_mm: f64,
}

/// The neighbour pairs an overlay draws ([`Overlay::pairs`]).
#[derive(Clone, Debug, Default)]
pub struct DetectorPairs {
    /// Outliers in the frame, not (yet) split.
    pub outliers: Vec<[[f64; 2]; 2]>,
    /// Counted as split: across the cut.
    pub split: Vec<[[f64; 2]; 2]>,
}

/// Draws the overlay: background (picture or true silhouette), the model tinted with its front
/// wireframe, the true silhouette's outline over it, tracked and virtual features, the true
/// and the detected cut with its separation points, the internal targets, then the title and
/// a legend of what is drawn.
///
/// `legend` is the corner the legend took in the previous frame of the same sequence (`None`
/// for the first): it stays there until the object moves under it, so that the legend of a
/// video does not jump from corner to corner. The corner taken is written back.
pub fn draw(o: &Overlay<'_>, legend_at: &mut Option<Corner>) -> Canvas {
    let mut canvas = match o.picture {
        Some(image) => Canvas {
            image: image.clone(),
        },
        None => {
            let mut c = Canvas::new(o.model_mask.width, o.model_mask.height, colour::BACKGROUND);
            if let Some(t) = o.truth_mask {
                c.tint(t, colour::TRUTH, 1.0);
            }
            c
        }
    };
    canvas.tint(o.model_mask, colour::MODEL, 0.3);
    canvas.front_wireframe(o.camera, o.positions, o.surface, colour::MODEL);
    // The true silhouette's outline on top, so that the model does not hide it.
    if let Some(t) = o.truth_mask {
        canvas.outline(t, colour::TRUTH_OUTLINE);
    }
    for obs in o.observations {
        canvas.dot(obs.uv, 2.0, colour::FEATURE);
    }
    for &uv in o.virtual_features {
        canvas.cross_mark(uv, 1.5, colour::VIRTUAL);
    }
    for &uv in o.filtered {
        canvas.ring(uv, 5.0, colour::FILTERED);
    }
    for line in o.true_cut.unwrap_or_default() {
        canvas.polyline(line, colour::TRUE_CUT, 1);
    }
    if let Some(pairs) = o.pairs {
        for &[a, b] in &pairs.outliers {
            canvas.line(a, b, colour::OUTLIER_PAIR);
        }
        for &[a, b] in &pairs.split {
            canvas.line(a, b, colour::SPLIT_PAIR);
        }
    }
    for &p in o.separation_points {
        canvas.dot(p, 1.0, colour::CUT);
    }
    canvas.polyline(o.cut_line, colour::CUT, 3);
    if let Some(h) = &o.farthest {
        for [p, q] in [h.line_worst, h.cut_worst] {
            canvas.line(p, q, colour::FARTHEST);
            canvas.ring(p, 6.0, colour::FARTHEST);
        }
    }
    for p in o.targets {
        if let Ok(uv) = o.camera.project(&Vector3::from(*p), 0) {
            canvas.cross_mark([uv.x, uv.y], 3.0, colour::TARGET);
        }
    }
    let mut title = format!("{}  frame {}", o.scene, o.frame);
    if o.dice.is_finite() {
        title.push_str(&format!("  Dice {:.3}", o.dice));
    }
    if o.target_error_mm.is_finite() && !o.targets.is_empty() {
        title.push_str(&format!("  target error {:.1} mm", o.target_error_mm));
    }
    canvas.title(&title);
    let mut legend = vec![];
    if o.truth_mask.is_some() {
        legend.push((colour::TRUTH_OUTLINE, "true silhouette"));
    }
    legend.push((colour::MODEL, "model (mesh)"));
    legend.push((colour::FEATURE, "tracked features"));
    legend.push((colour::VIRTUAL, "model's features"));
    if !o.filtered.is_empty() {
        legend.push((colour::FILTERED, "taken out by the filter"));
    }
    if !o.targets.is_empty() {
        legend.push((colour::TARGET, "internal targets"));
    }
    if o.true_cut.is_some() {
        legend.push((colour::TRUE_CUT, "true cut"));
    }
    legend.push((colour::CUT, "detected cut"));
    if o.farthest.is_some() {
        legend.push((colour::FARTHEST, "farthest apart"));
    }
    if o.pairs.is_some() {
        legend.push((colour::OUTLIER_PAIR, "outlier pairs"));
        legend.push((colour::SPLIT_PAIR, "split pairs"));
    }
    let corner = legend_corner(
        &canvas,
        &legend,
        &[Some(o.model_mask), o.truth_mask],
        &drawn_lines(o),
        *legend_at,
    );
    canvas.legend(&legend, corner);
    *legend_at = Some(corner);
    canvas
}

/// What one pixel of a drawn pair of the detector weighs against one pixel of the object when
/// the legend's corner is chosen: a few pixels wide, a legend over a stretch of them hides more
/// than over as many pixels of the object's inside.
const LINE_WEIGHT: usize = 8;

/// The segments an overlay draws that the legend should not hide.
struct DrawnLines {
    /// The detected and the true cut, and the strokes between where they are farthest apart.
    cuts: Vec<[[f64; 2]; 2]>,
    /// The detector's pairs, when asked for.
    pairs: Vec<[[f64; 2]; 2]>,
}

fn drawn_lines(o: &Overlay<'_>) -> DrawnLines {
    let polylines =
        std::iter::once(o.cut_line).chain(o.true_cut.unwrap_or_default().iter().map(Vec::as_slice));
    let farthest = o.farthest.iter().flat_map(|h| [h.line_worst, h.cut_worst]);
    let cuts = polylines
        .flat_map(|line| line.windows(2).map(|w| [w[0], w[1]]))
        .chain(farthest)
        .collect();
    let pairs = o
        .pairs
        .map(|p| p.outliers.iter().chain(&p.split).copied().collect())
        .unwrap_or_default();
    DrawnLines { cuts, pairs }
}

/// The corner where the legend hides the least of the picture: first the fewest pixels of the
/// cut lines (`lines.cuts`: a picture of a cut is about them, and weighed against the object's
/// pixels, as before, a short line lost to a corner the object filled more elsewhere), then
/// the fewest of `masks` (the model's and the true silhouette) and of the pairs (`lines.pairs`,
/// [`LINE_WEIGHT`] each), lines sampled a pixel apart; top right on a tie. A fixed corner hid
/// whatever the scene put there (a band's pulled end, a lobe, a false line). The corner `keep`
/// is kept while it hides no more of the cut lines than the best and the best hides less than a
/// fifth less of the rest.
fn legend_corner(
    canvas: &Canvas,
    legend: &[([u8; 3], &str)],
    masks: &[Option<&Mask>],
    lines: &DrawnLines,
    keep: Option<Corner>,
) -> Corner {
    let (w, h) = Canvas::legend_size(legend);
    let covered = |corner: Corner| {
        let (x0, y0) = canvas.legend_origin(legend, corner);
        let mut n = 0usize;
        for mask in masks.iter().flatten() {
            let xs = x0.max(0)..(x0 + i64::from(w)).min(i64::from(mask.width));
            let ys = y0.max(0)..(y0 + i64::from(h)).min(i64::from(mask.height));
            for y in ys {
                n += xs.clone().filter(|&x| mask.get(x as u32, y as u32)).count();
            }
        }
        let inside = |p: [f64; 2]| {
            let (x, y) = (p[0].floor() as i64, p[1].floor() as i64);
            (x0..x0 + i64::from(w)).contains(&x) && (y0..y0 + i64::from(h)).contains(&y)
        };
        let samples_inside = |segments: &[[[f64; 2]; 2]]| {
            let mut on = 0usize;
            for &[a, b] in segments {
                let samples = ((b[0] - a[0]).hypot(b[1] - a[1]).ceil() as usize).max(1);
                on += (0..=samples)
                    .filter(|&k| {
                        let t = k as f64 / samples as f64;
                        inside([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])])
                    })
                    .count();
            }
            on
        };
        (
            samples_inside(&lines.cuts),
            n + LINE_WEIGHT * samples_inside(&lines.pairs),
        )
    };
    // `min_by_key` keeps the first of equal keys: the preferred corner wins a tie.
    let best = Corner::ALL
        .into_iter()
        .min_by_key(|&c| covered(c))
        .unwrap_or(Corner::TopRight);
    match keep {
        Some(k) => {
            let (b, k_hides) = (covered(best), covered(k));
            // A fifth less hidden is worth a move; less is not (no flicker between corners
            // that hide about as much). Uncovering a cut line always is.
            if k_hides.0 <= b.0 && 5 * b.1 >= 4 * k_hides.1 {
                k
            } else {
                best
            }
        }
        None => best,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn no_lines() -> DrawnLines {
        DrawnLines {
            cuts: vec![],
            pairs: vec![],
        }
    }

    #[test]
    fn the_farthest_points_are_ringed_and_joined_across() {
        let camera = crate::generate::test_camera();
        let mask = Mask::from_fn(320, 200, |_, _| false);
        let (line, cut) = (
            [[40.0, 150.0], [80.0, 150.0]],
            vec![vec![[40.0, 160.0], [120.0, 160.0]]],
        );
        let farthest = crate::metrics::directed_hausdorff_to_parts(&line, &cut);
        let overlay = |farthest| Overlay {
            scene: "test",
            frame: 0,
            camera: &camera,
            picture: None,
            virtual_features: &[],
            separation_points: &[],
            pairs: None,
            positions: &[],
            surface: &[],
            model_mask: &mask,
            truth_mask: None,
            true_cut: Some(&cut),
            observations: &[],
            filtered: &[],
            cut_line: &line,
            farthest,
            targets: &[],
            dice: f64::NAN,
            target_error_mm: f64::NAN,
        };
        let pixel = |c: &Canvas, p: [u32; 2]| c.image.get_pixel(p[0], p[1]).0;
        let drawn = draw(&overlay(farthest), &mut None);
        // The cut's end (120, 160) is farthest from the line (its nearest point (80, 150)):
        // ringed, and the stroke between them drawn half way along.
        assert_eq!(pixel(&drawn, [126, 160]), colour::FARTHEST);
        assert_eq!(pixel(&drawn, [100, 155]), colour::FARTHEST);
        // Without a distance, neither.
        let plain = draw(&overlay(None), &mut None);
        assert_ne!(pixel(&plain, [126, 160]), colour::FARTHEST);
        assert_ne!(pixel(&plain, [100, 155]), colour::FARTHEST);
    }

    #[test]
    fn the_legend_goes_where_it_hides_least_of_the_object() {
        let canvas = Canvas::new(320, 200, [0, 0, 0]);
        let legend = [([1, 2, 3], "model (mesh)"), ([4, 5, 6], "true cut")];
        // Nothing to hide, or the object on the left: the preferred top right corner.
        let empty = Mask::from_fn(320, 200, |_, _| false);
        assert_eq!(
            legend_corner(&canvas, &legend, &[Some(&empty), None], &no_lines(), None),
            Corner::TopRight
        );
        let left = Mask::from_fn(320, 200, |x, _| x < 160);
        assert_eq!(
            legend_corner(&canvas, &legend, &[Some(&left), None], &no_lines(), None),
            Corner::TopRight
        );
        // The object on the right: top left.
        let right = Mask::from_fn(320, 200, |x, _| x >= 160);
        assert_eq!(
            legend_corner(&canvas, &legend, &[Some(&right), None], &no_lines(), None),
            Corner::TopLeft
        );
        // The model across the top, the truth down the left side: bottom right, where
        // neither is.
        let top = Mask::from_fn(320, 200, |_, y| y < 120);
        assert_eq!(
            legend_corner(
                &canvas,
                &legend,
                &[Some(&top), Some(&left)],
                &no_lines(),
                None
            ),
            Corner::BottomRight
        );
        // A corner taken before stays while another would hide about as much (the object
        // all over the picture but a strip along the top), and is left once another hides a
        // fifth less.
        let strip = Mask::from_fn(320, 200, |_, y| y >= 30);
        for corner in [Corner::TopRight, Corner::BottomLeft] {
            let keep = Some(corner);
            assert_eq!(
                legend_corner(&canvas, &legend, &[Some(&strip), None], &no_lines(), keep),
                corner
            );
        }
        assert_eq!(
            legend_corner(
                &canvas,
                &legend,
                &[Some(&right), None],
                &no_lines(),
                Some(Corner::TopRight)
            ),
            Corner::TopLeft
        );
        // The object under every corner alike (all of the picture): a line through the top
        // right corner, where the legend would go on the tie, sends it to a corner free of
        // lines.
        let all = Mask::from_fn(320, 200, |_, _| true);
        let (x, y) = canvas.legend_origin(&legend, Corner::TopRight);
        let (lw, lh) = Canvas::legend_size(&legend);
        let (x, y, lw, lh) = (x as f64, y as f64, f64::from(lw), f64::from(lh));
        let across_top_right = [[x - 5.0, y + lh / 2.0], [x + lw + 5.0, y + lh / 2.0]];
        let corner = legend_corner(
            &canvas,
            &legend,
            &[Some(&all), None],
            &DrawnLines {
                cuts: vec![],
                pairs: vec![across_top_right],
            },
            None,
        );
        assert_ne!(corner, Corner::TopRight);
        // A line across the whole top, under both top corners: a bottom corner.
        let across_the_top = [[0.0, y + lh / 2.0], [319.0, y + lh / 2.0]];
        let corner = legend_corner(
            &canvas,
            &legend,
            &[Some(&all), None],
            &DrawnLines {
                cuts: vec![],
                pairs: vec![across_the_top],
            },
            None,
        );
        assert!(
            matches!(corner, Corner::BottomLeft | Corner::BottomRight),
            "{corner:?}"
        );
        // A short cut line under the corner kept (band-01's slit under the legend, frame 10):
        // the legend leaves it for a corner that hides more of the object but none of the
        // line, however much more of the object.
        // The object everywhere but the bottom left quarter.
        let but_bottom_left = Mask::from_fn(320, 200, |x, y| x >= 160 || y < 100);
        let (x, y) = canvas.legend_origin(&legend, Corner::BottomLeft);
        let (x, y) = (x as f64, y as f64);
        let slit = [[x + 10.0, y + 5.0], [x + 12.0, y + 15.0]];
        let corner = legend_corner(
            &canvas,
            &legend,
            &[Some(&but_bottom_left), None],
            &DrawnLines {
                cuts: vec![slit],
                pairs: vec![],
            },
            Some(Corner::BottomLeft),
        );
        assert_ne!(corner, Corner::BottomLeft);
        // Without the line the legend stays where it hides none of the object.
        let corner = legend_corner(
            &canvas,
            &legend,
            &[Some(&but_bottom_left), None],
            &no_lines(),
            Some(Corner::BottomLeft),
        );
        assert_eq!(corner, Corner::BottomLeft);
        // The box drawn there stays inside the picture, below the title band on top.
        for corner in Corner::ALL {
            let (x, y) = canvas.legend_origin(&legend, corner);
            let (w, h) = Canvas::legend_size(&legend);
            assert!(x >= 0 && x + i64::from(w) <= 320, "{corner:?}");
            assert!(y >= 20 && y + i64::from(h) <= 200, "{corner:?}");
        }
    }
}
