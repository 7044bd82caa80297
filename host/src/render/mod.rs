//! Pictures: binary silhouettes rasterised at the camera's resolution, and RGB overlays (the
//! frame or the true silhouette, the model's wireframe, features, the cut polyline).

pub mod overlay;

use std::path::Path;

use image::{GrayImage, Luma, Rgb, RgbImage};
use incise_core::Camera;
use incise_core::nalgebra::Vector3;

/// A binary image at camera resolution: a pixel is set when its centre lies inside the shape.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Mask {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Row-major, one byte a pixel, 0 or 1.
    pub data: Vec<u8>,
}

impl Mask {
    /// An empty mask.
    pub fn new(width: u32, height: u32) -> Self {
        Mask {
            width,
            height,
            data: vec![0; width as usize * height as usize],
        }
    }

    /// A mask set where `inside(x, y)`.
    pub fn from_fn(width: u32, height: u32, inside: impl Fn(u32, u32) -> bool) -> Self {
        let mut m = Mask::new(width, height);
        for y in 0..height {
            for x in 0..width {
                m.data[(y * width + x) as usize] = u8::from(inside(x, y));
            }
        }
        m
    }

    /// Whether pixel `(x, y)` is set (false outside).
    pub fn get(&self, x: u32, y: u32) -> bool {
        x < self.width && y < self.height && self.data[(y * self.width + x) as usize] != 0
    }

    /// Number of set pixels.
    pub fn count(&self) -> usize {
        self.data.iter().filter(|&&v| v != 0).count()
    }

    /// Sets every pixel whose centre `(x + ½, y + ½)` lies inside the triangle (either
    /// orientation). Pixels on a shared edge belong to exactly one of the two triangles (the
    /// top-left rule), so a closed surface has no cracks and no double counting.
    pub fn fill_triangle(&mut self, t: [[f64; 2]; 3]) {
        let width = self.width;
        rasterize_triangle(self.width, self.height, t, |x, y, _| {
            self.data[(y * width + x) as usize] = 1;
        });
    }

    /// Writes the mask as an 8-bit grey PNG (0 and 255).
    ///
    /// # Errors
    /// If the file cannot be written.
    pub fn save_png(&self, path: &Path) -> Result<(), image::ImageError> {
        let img = GrayImage::from_fn(self.width, self.height, |x, y| {
            Luma([if self.get(x, y) { 255 } else { 0 }])
        });
        img.save(path)
    }

    /// Reads a grey or colour PNG; a pixel is set when its luma is at least 128.
    ///
    /// # Errors
    /// The image crate's error if the file cannot be read or decoded (it does not name the
    /// file: the caller does, once).
    pub fn load_png(path: &Path) -> Result<Mask, image::ImageError> {
        let img = image::open(path)?.to_luma8();
        let (width, height) = img.dimensions();
        let data = img.pixels().map(|p| u8::from(p.0[0] >= 128)).collect();
        Ok(Mask {
            width,
            height,
            data,
        })
    }
}

/// Calls `visit(x, y, weights)` for every pixel of a `width × height` image whose centre
/// `(x + ½, y + ½)` lies inside the triangle `t` (either orientation), with the barycentric
/// weights of the centre for the corners of `t` in their given order. Pixels on an edge
/// shared by two triangles are visited for exactly one of them (the top-left rule).
pub fn rasterize_triangle(
    width: u32,
    height: u32,
    t: [[f64; 2]; 3],
    mut visit: impl FnMut(u32, u32, [f64; 3]),
) {
    let area = cross(t[0], t[1], t[2]);
    if !(area.abs() > 0.0) || t.iter().flatten().any(|c| !c.is_finite()) {
        return;
    }
    // Work on a counter-clockwise copy (in x right, y down pixel coordinates); `order` maps
    // its corners back to the caller's.
    let (t, order) = if area < 0.0 {
        ([t[0], t[2], t[1]], [0, 2, 1])
    } else {
        (t, [0, 1, 2])
    };
    let area = area.abs();
    let xmin = t.iter().map(|p| p[0]).fold(f64::INFINITY, f64::min);
    let xmax = t.iter().map(|p| p[0]).fold(f64::NEG_INFINITY, f64::max);
    let ymin = t.iter().map(|p| p[1]).fold(f64::INFINITY, f64::min);
    let ymax = t.iter().map(|p| p[1]).fold(f64::NEG_INFINITY, f64::max);
    let x0 = (xmin - 0.5).floor().max(0.0) as u32;
    let y0 = (ymin - 0.5).floor().max(0.0) as u32;
    let x1 = ((xmax - 0.5).ceil().max(-1.0) as i64).min(width as i64 - 1);
    let y1 = ((ymax - 0.5).ceil().max(-1.0) as i64).min(height as i64 - 1);
    if x1 < 0 || y1 < 0 {
        return;
    }
    // Edge k is opposite corner k, so its edge function is corner k's weight times the area.
    let edges = [(t[1], t[2]), (t[2], t[0]), (t[0], t[1])];
    for y in y0..=y1 as u32 {
        for x in x0..=x1 as u32 {
            let p = [x as f64 + 0.5, y as f64 + 0.5];
            let mut w = [0.0; 3];
            let inside = edges.iter().enumerate().all(|(k, &(a, b))| {
                let e = cross(a, b, p);
                w[k] = e / area;
                e > 0.0 || (e == 0.0 && top_left(a, b))
            });
            if inside {
                let mut weights = [0.0; 3];
                for k in 0..3 {
                    weights[order[k]] = w[k];
                }
                visit(x, y, weights);
            }
        }
    }
}

/// `(b − a) × (p − a)`: positive when `p` is left of `a → b` in pixel coordinates with `y` down,
/// i.e. inside a counter-clockwise (on screen: clockwise-looking) triangle.
fn cross(a: [f64; 2], b: [f64; 2], p: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
}

/// The top-left rule for edge `a → b` of a positively oriented triangle.
fn top_left(a: [f64; 2], b: [f64; 2]) -> bool {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    (dy == 0.0 && dx < 0.0) || dy > 0.0
}

/// Projects a triangle of world points; `None` if a corner is behind the camera.
pub fn project_triangle(
    camera: &Camera<f64>,
    positions: &[[f64; 3]],
    tri: [u32; 3],
) -> Option<[[f64; 2]; 3]> {
    let mut out = [[0.0; 2]; 3];
    for (k, &v) in tri.iter().enumerate() {
        let p = positions.get(v as usize)?;
        let uv = camera.project(&Vector3::from(*p), v as usize).ok()?;
        out[k] = [uv.x, uv.y];
    }
    Some(out)
}

/// The silhouette of a closed surface (`triangles` over `positions`, metres) seen by
/// `camera`: every pixel whose centre is covered by a projected triangle.
pub fn silhouette(camera: &Camera<f64>, positions: &[[f64; 3]], triangles: &[[u32; 3]]) -> Mask {
    let intr = camera.intrinsics();
    let mut mask = Mask::new(intr.width, intr.height);
    for &tri in triangles {
        if let Some(t) = project_triangle(camera, positions, tri) {
            mask.fill_triangle(t);
        }
    }
    mask
}

/// Height of one legend line, pixels.
const LEGEND_LINE: u32 = 14;

/// A corner of the picture, where [`Canvas::legend`] puts its box.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Corner {
    /// Below the title band, on the left.
    TopLeft,
    /// Below the title band, on the right.
    TopRight,
    /// At the bottom, on the left.
    BottomLeft,
    /// At the bottom, on the right.
    BottomRight,
}

impl Corner {
    /// The four corners, the preferred one (top right, away from the title's text) first.
    pub const ALL: [Corner; 4] = [
        Corner::TopRight,
        Corner::TopLeft,
        Corner::BottomRight,
        Corner::BottomLeft,
    ];
}

/// An RGB picture to draw overlays on.
#[derive(Clone, Debug)]
pub struct Canvas {
    /// The picture.
    pub image: RgbImage,
}

/// Colours used by the overlays.
pub mod colour {
    /// Background.
    pub const BACKGROUND: [u8; 3] = [24, 24, 28];
    /// True silhouette.
    pub const TRUTH: [u8; 3] = [90, 90, 100];
    /// Outline of the true silhouette, drawn over the model.
    pub const TRUTH_OUTLINE: [u8; 3] = [200, 200, 210];
    /// Model wireframe.
    pub const MODEL: [u8; 3] = [80, 200, 255];
    /// Tracked features.
    pub const FEATURE: [u8; 3] = [120, 255, 120];
    /// Projected virtual features.
    pub const VIRTUAL: [u8; 3] = [255, 80, 80];
    /// Cut polyline (detected).
    pub const CUT: [u8; 3] = [255, 255, 0];
    /// Cut polyline (ground truth).
    pub const TRUE_CUT: [u8; 3] = [255, 0, 255];
    /// Internal targets.
    pub const TARGET: [u8; 3] = [255, 255, 255];
    /// Neighbour pairs that are outliers in the frame (`incise run --pairs`).
    pub const OUTLIER_PAIR: [u8; 3] = [200, 0, 200];
    /// Neighbour pairs counted as split (`incise run --pairs`).
    pub const SPLIT_PAIR: [u8; 3] = [255, 160, 0];
    /// Features the temporal filter took out (rings about their tracked positions).
    pub const FILTERED: [u8; 3] = [170, 110, 255];
    /// Where the detected and the true cut are farthest apart (rings, with a stroke across).
    pub const FARTHEST: [u8; 3] = [255, 0, 0];
}

impl Canvas {
    /// A canvas filled with `background`.
    pub fn new(width: u32, height: u32, background: [u8; 3]) -> Self {
        Canvas {
            image: RgbImage::from_pixel(width, height, Rgb(background)),
        }
    }

    /// Paints the set pixels of `mask` with `colour`, blended by `alpha` in `[0, 1]`.
    pub fn tint(&mut self, mask: &Mask, colour: [u8; 3], alpha: f64) {
        for (x, y, px) in self.image.enumerate_pixels_mut() {
            if mask.get(x, y) {
                for c in 0..3 {
                    let v = f64::from(px.0[c]) * (1.0 - alpha) + f64::from(colour[c]) * alpha;
                    px.0[c] = v.round().clamp(0.0, 255.0) as u8;
                }
            }
        }
    }

    fn plot(&mut self, x: i64, y: i64, colour: [u8; 3]) {
        if x >= 0 && y >= 0 && (x as u32) < self.image.width() && (y as u32) < self.image.height() {
            self.image.put_pixel(x as u32, y as u32, Rgb(colour));
        }
    }

    /// A one-pixel line from `a` to `b` (pixel coordinates, clipped to the picture).
    pub fn line(&mut self, a: [f64; 2], b: [f64; 2], colour: [u8; 3]) {
        if !a.iter().chain(&b).all(|c| c.is_finite()) {
            return;
        }
        let steps = (b[0] - a[0]).abs().max((b[1] - a[1]).abs()).ceil().min(1e5) as i64;
        for s in 0..=steps.max(1) {
            let t = s as f64 / steps.max(1) as f64;
            let x = a[0] + t * (b[0] - a[0]);
            let y = a[1] + t * (b[1] - a[1]);
            self.plot(x.floor() as i64, y.floor() as i64, colour);
        }
    }

    /// A polyline through `points`.
    pub fn polyline(&mut self, points: &[[f64; 2]], colour: [u8; 3], thickness: u32) {
        for w in points.windows(2) {
            for d in 0..thickness as i64 {
                let o = d as f64 - (thickness as f64 - 1.0) / 2.0;
                self.line([w[0][0] + o, w[0][1]], [w[1][0] + o, w[1][1]], colour);
                self.line([w[0][0], w[0][1] + o], [w[1][0], w[1][1] + o], colour);
            }
        }
    }

    /// A filled disc of `radius` pixels at `p`.
    pub fn dot(&mut self, p: [f64; 2], radius: f64, colour: [u8; 3]) {
        if !(p[0].is_finite() && p[1].is_finite()) {
            return;
        }
        let r = radius.ceil() as i64;
        let (cx, cy) = (p[0].floor() as i64, p[1].floor() as i64);
        for dy in -r..=r {
            for dx in -r..=r {
                if ((dx * dx + dy * dy) as f64) <= radius * radius {
                    self.plot(cx + dx, cy + dy, colour);
                }
            }
        }
    }

    /// A circle of `radius` pixels about `p`, one pixel wide (24 chords).
    pub fn ring(&mut self, p: [f64; 2], radius: f64, colour: [u8; 3]) {
        let at = |k: usize| {
            let a = std::f64::consts::TAU * k as f64 / 24.0;
            [p[0] + radius * a.cos(), p[1] + radius * a.sin()]
        };
        for k in 0..24 {
            self.line(at(k), at(k + 1), colour);
        }
    }

    /// A small `×` of half-size `size` pixels at `p`.
    pub fn cross_mark(&mut self, p: [f64; 2], size: f64, colour: [u8; 3]) {
        self.line(
            [p[0] - size, p[1] - size],
            [p[0] + size, p[1] + size],
            colour,
        );
        self.line(
            [p[0] - size, p[1] + size],
            [p[0] + size, p[1] - size],
            colour,
        );
    }

    /// The edges of the triangles of `triangles` (outward oriented) that face `camera`, so
    /// that the far side of the surface does not clutter the picture.
    pub fn front_wireframe(
        &mut self,
        camera: &Camera<f64>,
        positions: &[[f64; 3]],
        triangles: &[[u32; 3]],
        colour: [u8; 3],
    ) {
        let front: Vec<[u32; 3]> = triangles
            .iter()
            .copied()
            .filter(|t| {
                let p = t.map(|v| Vector3::from(positions[v as usize]));
                let eye = camera.viewpoint_for(&p[0]);
                (p[1] - p[0]).cross(&(p[2] - p[0])).dot(&(eye - p[0])) > 0.0
            })
            .collect();
        self.wireframe(camera, positions, &front, colour);
    }

    /// The edges of `triangles` over `positions` projected by `camera`.
    pub fn wireframe(
        &mut self,
        camera: &Camera<f64>,
        positions: &[[f64; 3]],
        triangles: &[[u32; 3]],
        colour: [u8; 3],
    ) {
        for &tri in triangles {
            if let Some(t) = project_triangle(camera, positions, tri) {
                for k in 0..3 {
                    // Each interior edge is shared by two triangles: draw it once.
                    if tri[k] < tri[(k + 1) % 3] {
                        self.line(t[k], t[(k + 1) % 3], colour);
                    }
                }
            }
        }
    }

    /// Darkens the rectangle at `(x, y)` of `w × h` pixels (clipped), so that text on it reads
    /// over any picture.
    pub fn shade(&mut self, x: i64, y: i64, w: u32, h: u32) {
        for py in y.max(0)..(y + i64::from(h)).min(i64::from(self.image.height())) {
            for px in x.max(0)..(x + i64::from(w)).min(i64::from(self.image.width())) {
                let p = self.image.get_pixel_mut(px as u32, py as u32);
                for c in &mut p.0 {
                    *c = (u16::from(*c) * 2 / 7) as u8;
                }
            }
        }
    }

    /// Writes `text` with its top left corner at `(x, y)` in an 8 × 8 bitmap font scaled by
    /// `scale` (characters outside ASCII are drawn as `?`).
    pub fn text(&mut self, x: i64, y: i64, text: &str, colour: [u8; 3], scale: u32) {
        let s = i64::from(scale.max(1));
        for (k, ch) in text.chars().enumerate() {
            let code = if ch.is_ascii() {
                ch as usize
            } else {
                '?' as usize
            };
            let glyph = font8x8::legacy::BASIC_LEGACY[code];
            let left = x + k as i64 * 8 * s;
            for (row, bits) in glyph.iter().enumerate() {
                for col in 0..8 {
                    if bits & (1 << col) != 0 {
                        for dy in 0..s {
                            for dx in 0..s {
                                self.plot(left + col * s + dx, y + row as i64 * s + dy, colour);
                            }
                        }
                    }
                }
            }
        }
    }

    /// Width in pixels of `text` written by [`Canvas::text`] at `scale`.
    pub fn text_width(text: &str, scale: u32) -> u32 {
        text.chars().count() as u32 * 8 * scale.max(1)
    }

    /// A title line on a shaded band across the top of the picture.
    pub fn title(&mut self, text: &str) {
        let width = self.image.width();
        self.shade(0, 0, width, 20);
        self.text(6, 6, text, [235, 235, 235], 1);
    }

    /// Width and height in pixels of the legend box [`Canvas::legend`] draws for `entries`.
    pub fn legend_size(entries: &[([u8; 3], &str)]) -> (u32, u32) {
        let longest = entries
            .iter()
            .map(|(_, t)| Canvas::text_width(t, 1))
            .max()
            .unwrap_or(0);
        (longest + 30, entries.len() as u32 * LEGEND_LINE + 8)
    }

    /// The top left corner of the legend box for `entries` in `corner`: 4 pixels from the
    /// picture's edges, below the title band at the top.
    pub fn legend_origin(&self, entries: &[([u8; 3], &str)], corner: Corner) -> (i64, i64) {
        let (w, h) = Canvas::legend_size(entries);
        let (width, height) = (
            i64::from(self.image.width()),
            i64::from(self.image.height()),
        );
        let x = match corner {
            Corner::TopLeft | Corner::BottomLeft => 4,
            Corner::TopRight | Corner::BottomRight => width - i64::from(w) - 4,
        };
        let y = match corner {
            Corner::TopLeft | Corner::TopRight => 24,
            Corner::BottomLeft | Corner::BottomRight => height - i64::from(h) - 4,
        };
        (x, y)
    }

    /// A legend in `corner`: a colour swatch and its meaning per line, on a shaded box.
    pub fn legend(&mut self, entries: &[([u8; 3], &str)], corner: Corner) {
        let (x, y) = self.legend_origin(entries, corner);
        let (w, h) = Canvas::legend_size(entries);
        self.shade(x, y, w, h);
        let line = i64::from(LEGEND_LINE);
        for (k, (colour, label)) in entries.iter().enumerate() {
            let top = y + 4 + k as i64 * line;
            for dy in 1..9 {
                for dx in 0..14 {
                    self.plot(x + 6 + dx, top + dy, *colour);
                }
            }
            self.text(x + 24, top + 1, label, [235, 235, 235], 1);
        }
    }

    /// Paints the boundary pixels of `mask` (set pixels with an unset 4-neighbour): an outline
    /// that stays visible over whatever is drawn inside.
    pub fn outline(&mut self, mask: &Mask, colour: [u8; 3]) {
        let (w, h) = (mask.width, mask.height);
        for y in 0..h {
            for x in 0..w {
                if mask.get(x, y)
                    && (x == 0
                        || y == 0
                        || x + 1 == w
                        || y + 1 == h
                        || !mask.get(x - 1, y)
                        || !mask.get(x + 1, y)
                        || !mask.get(x, y - 1)
                        || !mask.get(x, y + 1))
                {
                    self.plot(i64::from(x), i64::from(y), colour);
                }
            }
        }
    }

    /// Writes the picture as PNG.
    ///
    /// # Errors
    /// If the file cannot be written.
    pub fn save(&self, path: &Path) -> Result<(), image::ImageError> {
        self.image.save(path)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_triangles_of_a_square_cover_it_exactly_once() {
        let (a, b, c, d) = ([1.0, 1.0], [9.0, 1.0], [9.0, 7.0], [1.0, 7.0]);
        let mut one = Mask::new(12, 10);
        one.fill_triangle([a, b, c]);
        let first = one.count();
        one.fill_triangle([a, c, d]);
        // 8 × 6 pixel centres inside the square, none counted twice or missed.
        assert_eq!(one.count(), 48);
        let mut other = Mask::new(12, 10);
        other.fill_triangle([a, c, d]);
        assert_eq!(first + other.count(), 48);
    }

    #[test]
    fn orientation_and_clipping_do_not_matter() {
        let mut m1 = Mask::new(8, 8);
        m1.fill_triangle([[-5.0, -5.0], [20.0, -5.0], [-5.0, 20.0]]);
        let mut m2 = Mask::new(8, 8);
        m2.fill_triangle([[-5.0, -5.0], [-5.0, 20.0], [20.0, -5.0]]);
        assert_eq!(m1, m2);
        assert_eq!(m1.count(), 64);
        let mut m3 = Mask::new(8, 8);
        m3.fill_triangle([[f64::NAN, 0.0], [1.0, 1.0], [2.0, 0.0]]);
        assert_eq!(m3.count(), 0);
    }

    /// The pixels of `c` painted `colour`.
    fn lit(c: &Canvas, colour: [u8; 3]) -> Vec<(u32, u32)> {
        c.image
            .enumerate_pixels()
            .filter(|(_, _, p)| p.0 == colour)
            .map(|(x, y, _)| (x, y))
            .collect()
    }

    #[test]
    fn text_legend_and_outline_stay_where_they_are_put() {
        let mut c = Canvas::new(200, 100, [0, 0, 0]);
        c.text(10, 10, "Ab", [255, 255, 255], 2);
        let lit = lit(&c, [255, 255, 255]);
        assert!(!lit.is_empty());
        let w = Canvas::text_width("Ab", 2);
        assert_eq!(w, 32);
        assert!(
            lit.iter()
                .all(|&(x, y)| (10..10 + w).contains(&x) && (10..26).contains(&y))
        );
        // Off the picture, and characters outside ASCII: drawn as far as they fit, no panic.
        c.text(190, 95, "é—x", [1, 2, 3], 3);
        c.legend(
            &[([9, 9, 9], "a very long legend line that does not fit")],
            Corner::BottomLeft,
        );
        c.title("title");
        let mut m = Mask::new(20, 20);
        m.fill_triangle([[2.0, 2.0], [18.0, 2.0], [2.0, 18.0]]);
        let mut o = Canvas::new(20, 20, [0, 0, 0]);
        o.outline(&m, [255, 0, 0]);
        let edge = o.image.pixels().filter(|p| p.0 == [255, 0, 0]).count();
        assert!(edge > 0 && edge < m.count(), "{edge} of {}", m.count());
        assert_ne!(o.image.get_pixel(3, 3).0, [255, 0, 0]);
    }

    #[test]
    fn a_ring_lies_on_its_circle_and_leaves_its_centre() {
        let mut c = Canvas::new(40, 40, [0, 0, 0]);
        c.ring([20.0, 20.0], 8.0, [9, 8, 7]);
        let lit = lit(&c, [9, 8, 7]);
        // About its circumference (2π · 8 ≈ 50 pixels), every pixel within a pixel and a half
        // of the circle (chords and the pixel grid).
        assert!(lit.len() >= 40, "{}", lit.len());
        for &(x, y) in &lit {
            let r = (f64::from(x) + 0.5 - 20.0).hypot(f64::from(y) + 0.5 - 20.0);
            assert!((r - 8.0).abs() <= 1.5, "({x}, {y}) at {r}");
        }
        // Partly off the picture: drawn as far as it fits.
        c.ring([1.0, 1.0], 6.0, [1, 1, 1]);
    }
}
