//! The stability envelope: each scene run over a grid of Young's modulus, Poisson ratio and
//! spring stiffness relative to the material, and each cell classified.
//!
//! The registration depends on the springs only through `k / E`, so the grid holds the
//! springs relative to the material at the scene's own coupling times a scale (`[solver]
//! coupling`, whose `k` follows `E` by itself) while `E` sweeps eight decades: `E` alone tests
//! the numerics (every energy and pivot scales with it), the scale tests how well posed the
//! coupling is.

use std::panic::{AssertUnwindSafe, catch_unwind};

use incise_core::solve::DEFAULT_COUPLING;
use serde::Serialize;

use crate::run::{Trace, run_once};
use crate::scene::Scene;

/// A frame converges when the gradient at its end is at most this fraction of its start.
pub(super) const CONVERGED_REDUCTION: f64 = 1e-3;

/// A cell converges when at least this fraction of its solved frames converge.
pub(super) const CONVERGED_FRAMES: f64 = 0.9;

/// What a cell came to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// Every position finite, no frame refused, the gradient reduced in enough frames.
    Converged,
    /// Every position finite, no frame refused, the gradient not reduced enough.
    NotConverged,
    /// The core refused frames with a typed error (the model going on as it was).
    TypedError,
    /// A non-finite position or a panic: a bug.
    Failure,
}

impl Status {
    /// A short label.
    pub(super) fn label(self) -> &'static str {
        match self {
            Status::Converged => "converged",
            Status::NotConverged => "not converged",
            Status::TypedError => "typed error",
            Status::Failure => "failure",
        }
    }
}

/// One cell of the grid.
#[derive(Clone, Debug, Serialize)]
pub struct Cell {
    /// Young's modulus, pascals.
    pub young: f64,
    /// Poisson ratio.
    pub poisson: f64,
    /// The springs' stiffness over the scene's own, relative to the material: the scene's
    /// `coupling` times this (or its `k / E` times `E` times this, for a scene that gives `k`).
    pub k_scale: f64,
    /// The spring stiffness `k` in service, J/px² (NaN when the run was refused).
    pub spring_stiffness: f64,
    /// What the cell came to.
    pub status: Status,
    /// Frames the core refused, and the first refusal's message.
    pub frames_rejected: usize,
    /// The first refusal.
    pub first_error: Option<String>,
    /// Fraction of solved frames whose gradient fell by [`CONVERGED_REDUCTION`].
    pub converged_frames: f64,
    /// Smallest pivot of the factor over the run.
    pub min_pivot: f64,
    /// Largest ratio of the largest to the smallest pivot (a lower bound of the condition
    /// number of the factored matrix).
    pub pivot_ratio: f64,
    /// Dice of the last frame.
    pub dice_final: f64,
    /// Target error of the last frame, millimetres.
    pub tre_mm_final: f64,
    /// Target error of the rest model left in place, millimetres.
    pub tre_mm_rest: f64,
}

/// The grid: `(young, poisson, k_scale)` for each cell. Default: `E` in 10², 10⁵, 10⁹ Pa, ν in
/// 0, 0.45, 0.499, the springs' scale in 10⁻⁶ … 10⁶ by factors of 1000; `--quick`: the
/// scene's own `E` and ν, the scale in 10⁻³, 1, 10³.
pub(super) fn grid(scene: &Scene, quick: bool) -> Vec<(f64, f64, f64)> {
    let own = (scene.file.model.young, scene.file.model.poisson);
    let (youngs, poissons, scales): (Vec<f64>, Vec<f64>, Vec<f64>) = if quick {
        (vec![own.0], vec![own.1], vec![1e-3, 1.0, 1e3])
    } else {
        (
            vec![1e2, 1e5, 1e9],
            vec![0.0, 0.45, 0.499],
            vec![1e-6, 1e-3, 1.0, 1e3, 1e6],
        )
    };
    let mut cells = vec![];
    for &e in &youngs {
        for &nu in &poissons {
            for &s in &scales {
                cells.push((e, nu, s));
            }
        }
    }
    cells
}

/// Runs `scene` (cutting on) with one cell's material and springs.
pub(super) fn run_cell(scene: &Scene, (young, poisson, k_scale): (f64, f64, f64)) -> Cell {
    let own = &scene.file;
    let mut s = scene.clone();
    s.file.model.young = young;
    s.file.model.poisson = poisson;
    // A derived `k` follows `E` by itself; a given one is scaled with it.
    match own.solver.spring_stiffness {
        Some(k) => s.file.solver.spring_stiffness = Some(k / own.model.young * young * k_scale),
        None => {
            let beta = own.solver.coupling.unwrap_or(DEFAULT_COUPLING);
            s.file.solver.coupling = Some(beta * k_scale);
        }
    }
    let run = catch_unwind(AssertUnwindSafe(|| run_once(&s, true, None, false)));
    let mut cell = Cell {
        young,
        poisson,
        k_scale,
        spring_stiffness: f64::NAN,
        status: Status::Failure,
        frames_rejected: 0,
        first_error: None,
        converged_frames: 0.0,
        min_pivot: f64::NAN,
        pivot_ratio: f64::NAN,
        dice_final: f64::NAN,
        tre_mm_final: f64::NAN,
        tre_mm_rest: f64::NAN,
    };
    match run {
        Err(_) => cell.first_error = Some("panic".into()),
        Ok(Err(e)) => {
            // The run as a whole was refused (a configuration the core does not take).
            cell.status = Status::TypedError;
            cell.first_error = Some(e.to_string());
        }
        Ok(Ok(trace)) => classify(&mut cell, &trace),
    }
    cell
}

fn classify(cell: &mut Cell, trace: &Trace) {
    let health: Vec<_> = trace.frames.iter().filter_map(|r| r.health).collect();
    let finite = health.iter().all(|h| h.finite);
    let converged = health
        .iter()
        .filter(|h| h.gradient_after <= CONVERGED_REDUCTION * h.gradient_before)
        .count();
    cell.converged_frames = if health.is_empty() {
        0.0
    } else {
        converged as f64 / health.len() as f64
    };
    cell.min_pivot = health
        .iter()
        .map(|h| h.pivots.0)
        .fold(f64::INFINITY, f64::min);
    cell.pivot_ratio = health
        .iter()
        .map(|h| h.pivots.1 / h.pivots.0)
        .fold(0.0, f64::max);
    cell.frames_rejected = trace.rejected.len();
    cell.first_error = trace
        .rejected
        .first()
        .map(|(f, e)| format!("frame {f}: {e}"));
    cell.spring_stiffness = trace.spring_stiffness;
    cell.dice_final = trace.dice_final;
    cell.tre_mm_final = trace.tre_final * 1e3;
    cell.tre_mm_rest = trace.tre_rest_final * 1e3;
    cell.status = if !finite {
        Status::Failure
    } else if cell.frames_rejected > 0 {
        Status::TypedError
    } else if cell.converged_frames >= CONVERGED_FRAMES {
        Status::Converged
    } else {
        Status::NotConverged
    };
}
