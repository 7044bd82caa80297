//! Where a run's outputs go: overlay pictures to a [`FrameSink`] (an overlay video) and, with
//! an output directory, PNG stills, the deformed mesh per frame (VTU, with a `.pvd` series) and
//! `frames.csv` (the VTU files through [`crate::vtu`]).

use std::path::Path;

use image::RgbImage;
use incise_core::{Model, Real};

use crate::render::Canvas;
use crate::run::{FrameRecord, RunError, output};
use crate::vtu;

/// Where overlay pictures go besides PNG stills: an overlay video (the `opencv` feature).
pub trait FrameSink {
    /// Appends one overlay picture.
    ///
    /// # Errors
    /// A [`RunError`] if it cannot be written.
    fn write(&mut self, picture: &RgbImage) -> Result<(), RunError>;
}

/// The outputs of one pass: an output directory, a sink, or neither.
pub(crate) struct Outputs<'d, 's> {
    dir: Option<&'d Path>,
    sink: Option<&'s mut dyn FrameSink>,
    /// The `.pvd` series: time and file of each frame's mesh.
    pvd: Vec<(f64, String)>,
    /// `pairs.csv` so far (with an output directory and the detector's pairs asked for).
    pairs: Option<String>,
}

impl<'d, 's> Outputs<'d, 's> {
    /// Outputs to `dir` (created if missing) and `sink`.
    /// With `pairs`, `pairs.csv` too (in `dir`, if any).
    pub(crate) fn new(
        dir: Option<&'d Path>,
        sink: Option<&'s mut dyn FrameSink>,
        pairs: bool,
    ) -> Result<Self, RunError> {
        if let Some(dir) = dir {
            std::fs::create_dir_all(dir).map_err(output_at(dir))?;
        }
        Ok(Outputs {
            dir,
            sink,
            pvd: vec![],
            pairs: (pairs && dir.is_some()).then(|| PAIRS_CSV_HEADER.to_string()),
        })
    }

    /// Whether `pairs.csv` is written.
    pub(crate) fn wants_pairs(&self) -> bool {
        self.pairs.is_some()
    }

    /// Appends rows to `pairs.csv`.
    pub(crate) fn pairs(&mut self, rows: &str) {
        if let Some(csv) = self.pairs.as_mut() {
            csv.push_str(rows);
        }
    }

    /// Whether any output wants the overlay pictures.
    pub(crate) fn wants_overlay(&self) -> bool {
        self.dir.is_some() || self.sink.is_some()
    }

    /// Hands the overlay of frame `f` to the sink, then saves it as `frame_<f>.png`.
    pub(crate) fn overlay(&mut self, f: usize, canvas: &Canvas) -> Result<(), RunError> {
        if let Some(sink) = self.sink.as_deref_mut() {
            sink.write(&canvas.image)?;
        }
        if let Some(dir) = self.dir {
            let file = dir.join(format!("frame_{f:04}.png"));
            canvas.save(&file).map_err(output_at(&file))?;
        }
        Ok(())
    }

    /// Writes the model as it is after frame `f` as `mesh_<f>.vtu`.
    pub(crate) fn mesh<T: Real, F: Real>(
        &mut self,
        f: usize,
        model: &Model<'_, T, F>,
    ) -> Result<(), RunError> {
        if let Some(dir) = self.dir {
            let name = format!("mesh_{f:04}.vtu");
            let file = dir.join(&name);
            write_mesh_vtu(&file, model).map_err(output_at(&file))?;
            self.pvd.push((f as f64, name));
        }
        Ok(())
    }

    /// Writes the mesh series (`mesh.pvd`) and the per-frame records (`frames.csv`).
    pub(crate) fn finish(self, frames: &[FrameRecord]) -> Result<(), RunError> {
        if let Some(dir) = self.dir {
            let (pvd, csv) = (dir.join("mesh.pvd"), dir.join("frames.csv"));
            vtu::write_pvd(&pvd, &self.pvd).map_err(output_at(&pvd))?;
            write_frames_csv(&csv, frames).map_err(output_at(&csv))?;
            if let Some(rows) = &self.pairs {
                let file = dir.join("pairs.csv");
                std::fs::write(&file, rows).map_err(output_at(&file))?;
            }
        }
        Ok(())
    }
}

/// The columns of `pairs.csv`: per frame, every neighbour pair measured in it (see
/// [`pair_rows`](crate::run)).
const PAIRS_CSV_HEADER: &str = "frame,pair,id_i,id_j,u_i,v_i,u_j,v_j,difference_px,smooth_px,level_px,margin_px,outlier,split,crosses_true_cut\n";

/// An output error that names the file or directory it came from.
fn output_at<E: std::fmt::Display>(path: &Path) -> impl Fn(E) -> RunError + '_ {
    move |e| output(format!("{}: {e}", path.display()))
}

/// Writes the model as it is (cut, with its lips apart) as a VTU file at `path`, with the
/// displacement from rest.
///
/// # Errors
/// The I/O error of writing `path`.
fn write_mesh_vtu<T: Real, F: Real>(path: &Path, model: &Model<'_, T, F>) -> std::io::Result<()> {
    let x: Vec<[f64; 3]> = model.positions().iter().map(|p| p.map(T::to_f64)).collect();
    let disp: Vec<[f64; 3]> = x
        .iter()
        .zip(model.mesh().rest())
        .map(|(a, b)| {
            [
                a[0] - b[0].to_f64(),
                a[1] - b[1].to_f64(),
                a[2] - b[2].to_f64(),
            ]
        })
        .collect();
    vtu::write_vtu(
        path,
        &x,
        model.mesh().tets(),
        &[("displacement", &disp)],
        &[],
    )
}

/// Writes the per-frame records of a run as CSV (`frames.csv`).
///
/// # Errors
/// The I/O error of writing `path`.
fn write_frames_csv(path: &Path, frames: &[FrameRecord]) -> std::io::Result<()> {
    let mut csv = String::from(
        "frame,dice,tre_mm,step_ms,observed,outlier_pairs,separation_points,difference_median_px,difference_deviation_px,cut_vertices\n",
    );
    for r in frames {
        csv.push_str(&format!(
            "{},{:.5},{:.4},{:.3},{},{},{},{:.4},{:.4},{}\n",
            r.frame,
            r.dice,
            r.tre_mm,
            r.ms,
            r.observed,
            r.outlier_pairs,
            r.separation_points,
            r.difference_median_px,
            r.difference_deviation_px,
            r.cut_vertices
        ));
    }
    std::fs::write(path, csv)
}
