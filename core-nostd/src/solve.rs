//! The per-frame minimisation: assembly of the energy, its gradient and a positive definite
//! Hessian into the fixed stiffness pattern (`solve/assembly.rs`), and the Newton loop over it with the linear
//! strategies and a line search with a fixed number of trial steps (`solve/newton.rs`, the stage
//! [`crate::Model::step`] calls).
//!
//! The energy minimised over the free nodes is
//! `W(x) = W_I(x) + W_S(x) + W_D(x)`:
//! - `W_I`, the Saint Venant–Kirchhoff elastic energy of the mesh, with the inversion barrier
//!   on `det F` if the material asks for it ([`crate::material`]);
//! - `W_S = Σ k ρ(‖f_i − P(f_iˢ)‖)`, the springs between each observed feature `f_i` and the
//!   projection of its virtual feature as the springs see it, `f_iˢ = Σ_a w_a y_a`, with
//!   `y_a = x_a − e_a (e_a · (x_a − x_a⁻))`: each node of its element less its motion along its
//!   own camera ray `e_a` (through its previous position `x_a⁻`) since the frame began. So the
//!   springs act across the rays only, and how deep a node lies is decided by the elastic
//!   energy, the damping and the depth prior, however stiff the springs are. Through the full
//!   projection of `Σ_a w_a x_a`, whose pixel shifts a little when the nodes of its element move
//!   along their own, slightly different rays, stiff springs used that lever to fit the
//!   tracker's noise with depth: at 10⁴ times the default coupling the stiff band's targets
//!   ended 7.8 mm from the truth instead of 0.2, at 10⁶ times 176 mm; they now stay at 0.2 mm
//!   (the report's stability section sweeps the coupling from 10⁻⁶ to 10⁶ times its default).
//!   At a frame's end `f_iˢ` and `f_iᵛ = Σ_a w_a x_a` differ only by that lever on the frame's
//!   own depth motion. `ρ` is Huber's loss: `½ r²` up to
//!   a threshold `δ` ([`SolverConfig::spring_threshold`] feature spacings), `δ r − ½ δ²` beyond,
//!   so a feature the tracker lost to a wrong spot pulls with a bounded force instead of one
//!   that grows with its error. Gauss–Newton through `P` with the weight of iteratively
//!   reweighted least squares: the Hessian keeps `k w Qᵀ Jᵀ J Q`, `J = ∂P/∂x`, `Q` the
//!   projections `I − e_a e_aᵀ` of the element's nodes, `w = ρ'(r) / r` (1 inside the
//!   threshold, `δ / r` beyond), and drops the curvature of `P` and of `ρ`;
//! - `W_D = ½ Σ_a c_a ‖x_a − x_a⁻‖²`, a damping term toward the previous frame's positions
//!   `x⁻`, with `c_a` a fraction ([`SolverConfig::damping`]) of node `a`'s rest stiffness. It
//!   keeps the Hessian positive definite when features are lost and steadies the depth the
//!   monocular springs cannot see; at a frame's fixed point it vanishes, so it does not bias a
//!   converged registration.
//! - `W_R = ½ Σ_a r_a ((x_a − X_a) · e)²`, a prior on depth: each node's displacement from its
//!   rest position `X_a` along the optical axis `e` (the change of its depth in the camera
//!   frame), with `r_a` a fraction ([`SolverConfig::depth_prior`]) of its rest stiffness. A
//!   monocular camera sees no motion along its rays, so without it the model "explains" a
//!   stretch it sees by bulging toward the camera and bending, which an elastic model finds
//!   cheaper than stretching (a band pulled along its length arched 7 mm toward the camera and
//!   its unobserved end dipped 8 mm). The prior says: without evidence, the organ keeps its
//!   depth. It is weak next to the material (a tenth of the rest stiffness by default), so
//!   depth still follows what the elasticity and the features imply; it does not vanish at a
//!   fixed point, so it biases motion that truly changes depth. It used to act along the ray
//!   through each node's rest position instead, which also resists motion at constant depth:
//!   a node `θ` off the axis moved sideways by `s` has `s sin θ` along that ray, which the
//!   prior took back by moving it in depth (`band-middle-cut`, pulled 6.5 cm across a view
//!   ±8° wide, sank its targets 2–4 mm away from the camera: target error 2.26 mm, 1.30 mm
//!   along the axis; on the scene families the two are alike, see the README). With springs
//!   stiffer than the default coupling, `r_a` grows with them (times `k / k₀`, `k₀` the default coupling's stiffness for the
//!   scene, [`DEFAULT_COUPLING`]): the springs then hold the features' pixels harder than the
//!   model's shape can follow, and the elastic energy sheds what it cannot match by moving
//!   nodes along the rays, where nothing else resists (a band's targets went 3.3 → 12 mm from
//!   the truth at 10³ times the coupling, a liver's 2.3 → 34 mm at 10⁶). Keeping the prior's
//!   ratio to the springs keeps those frames as well posed as at the default; at or below it
//!   nothing changes.
//!
//! Above the default coupling the springs' Huber threshold shrinks by `k₀ / k`, so each
//! spring's largest force stays the default's ([`DEFAULT_SPRING_THRESHOLD`] says why).
//!
//! Every loop runs a number of times fixed by the configuration and the scene's sizes, so a
//! frame's cost does not depend on the data.

mod assembly;
mod kept;
mod newton;
mod secant;

pub(crate) use assembly::{ElementSums, Problem, build_scatter};
pub(crate) use kept::KeptElements;
#[cfg(feature = "cut")]
pub(crate) use newton::{AssemblyOutput, assemble_on, factorize_on};
pub use secant::SECANT_PAIRS;
pub(crate) use secant::SecantMemory;

use crate::error::{Error, Parameter};
use crate::real::Real;

/// The default of [`SolverConfig::spring_threshold`]: a spring is quadratic up to two feature
/// spacings of residual and linear beyond.
///
/// Why two spacings: tracking noise is a pixel or two and a model that follows its features
/// leaves residuals of a few pixels, all well inside it, so registration is the quadratic one
/// wherever the tracks are sound (against quadratic springs, the committed scenes' results
/// move by at most 0.0002 Dice and 0.13 mm). A feature off by more than two spacings is off by
/// more than the distance to its neighbours' neighbours: a lost track, or the far lip of a cut
/// the mesh does not have yet. Its pull is capped at `k δ`, so it no longer drags the volume
/// with it. At one spacing the uncut models gain more (the liver's targets end 0.6 mm nearer
/// the truth before its mesh is cut, against 0.2 mm at two), but the coarse liver, which
/// cannot follow its folds to within a spacing, then lets go of features there and its intact
/// variants (`fixtures/families/liver.toml`) are cut falsely 5 times in 10 instead of 3; at
/// half a spacing the live and middle cuts are found late or not at all.
///
/// Above the default coupling `δ` shrinks as the springs stiffen, `δ k₀ / k` (`k₀` the
/// default coupling's stiffness for the scene, [`DEFAULT_COUPLING`]), so the force a spring
/// can pull with stays the default's `k₀ δ` however stiff the springs are: stiffer springs hold
/// a feature the model can follow more tightly, and one it cannot follow pulls no harder. The
/// default already caps it generously: taken to the object, `k₀ δ` is 200 times the force that
/// would squeeze the cube of material one feature spacing wide to nothing
/// ([`DEFAULT_COUPLING`]), so a larger force could only tear the model toward features it
/// cannot match. With `δ` fixed instead, the cap grew with `k`, and the coarse liver, which
/// cannot follow its folds, was pulled out of shape by its own features: at 10⁴, 10⁵ and 10⁶
/// times the coupling its targets ended 1.1, 1.4 and 2.1 times the rest model's distance from
/// the truth (`incise report`'s stability section had 15 cells of 699 above 1.2 times, all the
/// liver's at 10⁶); with the force held the liver's end at 0.3–0.9 of it at 10⁶, and no cell
/// of the grid is above 1.2. The price is convergence: above the default the springs become
/// L1 ones with a kink a fraction of a pixel wide, which Newton's method resolves slowly, so at
/// 10³ and 10⁶ times the coupling no cell of the grid brings its gradient (the median over its
/// frames) below 0.01 of its start, even with 8 Newton steps (at the default nothing changes),
/// and the bands follow their cuts a little less
/// closely (`band-side-cut` at 10³: Dice 0.988 → 0.946, its targets 3.1 → 4.2 mm from the
/// truth, the rest model's 21.2 mm). Shrinking `δ` by `√(k₀ / k)` kept the liver sane too but
/// converged no better and lost more on the bands (0.929 at 10³).
pub const DEFAULT_SPRING_THRESHOLD: f64 = 2.0;

/// The default of [`SolverConfig::depth_prior`]: a tenth of the rest stiffness.
pub const DEFAULT_DEPTH_PRIOR: f64 = 0.1;

/// The default of [`Coupling::Relative`]: each feature's spring, taken to the object, is a
/// hundred times as stiff as a cube of the material one feature spacing wide.
///
/// Why a hundred: the springs must dominate the material around each feature, or the model
/// lags what it sees (at 30 the side cut's targets end 1.7 mm further from the truth); from
/// about 100 the committed scenes' results level off (within 0.002 Dice and 0.05 mm from 100 to
/// 300 on the intact scenes), and stiffer springs follow the tracker's noise into the volume (at
/// 300 the live cut's targets end 1.6 mm further out). `incise report` sweeps it from 10⁻⁶ to
/// 10⁶ times this on every scene (its stability section).
pub const DEFAULT_COUPLING: f64 = 100.0;

/// PCG iterations that refine each Newton step's solve under `Refactor` when the factor is
/// of lower precision than the model ([`crate::Model`] with `F = f32`, `T = f64`): each one
/// a matrix–vector product on the `f64` Hessian and a solve with the `f32` factor. One `f32`
/// solve alone leaves a relative error of about `κ · 6·10⁻⁸` (10⁻⁷ on the stiffness matrices
/// of `tests/sparse_ldl.rs`), and each refinement multiplies it by about as much: two reach
/// `f64`'s accuracy there, and settle a stiff cantilever as close to equilibrium as `f64` does
/// (`tests/model_solve.rs`). `Frozen` and `FactorOnce` refine already: their PCG iterations
/// run on the `f64` residual. Where the Hessian rounded to `f32` is no longer positive
/// definite (condition near `1/ε_f32`), the factorization fails with a typed error and only
/// `f64` solves the system.
pub const MIXED_REFINEMENT_STEPS: u32 = 2;

/// How stiff the springs between the features and the model are.
///
/// The springs act in the image (`k` in J/px²), so the same `k` means a stiff coupling for an
/// object seen close up and a loose one for the same object seen from afar, and a different one
/// for every material. [`Coupling::Relative`] states it in terms of the scene instead, and is
/// what a scene should use unless it has a measured `k`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Coupling<T> {
    /// `β`, dimensionless: each feature's spring, taken to the object, is `β` times as stiff
    /// as a cube of the material one feature spacing wide, `k · m² = β · E · s / m`, with `E`
    /// the Young's modulus, `s` the feature spacing in the image at frame 0 (the square root of
    /// the area of the features' bounding box over their number, pixels, as the detector
    /// measures it) and `m` the image scale at the features (pixels per metre: the mean over
    /// the virtual features of the smaller singular value of `∂P/∂x`, the magnification of
    /// motion across the ray: `f/z` for a perspective camera). `k = β · E · s / m³` is set when the features are embedded
    /// ([`crate::Model::embed_features`]) and kept through cuts, so a frame's energy does not
    /// change with what is seen.
    Relative(T),
    /// `k`, J/px², as given.
    Stiffness(T),
}

impl<T: Real> Coupling<T> {
    /// The spring stiffness `k`, J/px², for a material of Young's modulus `young`, features
    /// `spacing_px` apart in the image, seen at `scale` pixels per metre.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming [`Parameter::SpringStiffness`] if the result is not
    /// positive and finite.
    pub fn stiffness(&self, young: T, spacing_px: T, scale: T) -> Result<T, Error> {
        let k = match *self {
            Coupling::Relative(beta) => beta * young * spacing_px / (scale * scale * scale),
            Coupling::Stiffness(k) => k,
        };
        if k.finite() && k > T::zero() {
            Ok(k)
        } else {
            Err(Error::InvalidParameter {
                parameter: Parameter::SpringStiffness,
            })
        }
    }

    fn is_valid(&self) -> bool {
        let v = match *self {
            Coupling::Relative(v) | Coupling::Stiffness(v) => v,
        };
        v.finite() && v > T::zero()
    }
}

impl<T: Real> Default for Coupling<T> {
    fn default() -> Self {
        Coupling::Relative(T::of(DEFAULT_COUPLING))
    }
}

/// Upper bound on [`SolverConfig::newton_iterations`].
pub const MAX_NEWTON_ITERATIONS: u32 = 64;
/// Upper bound on [`SolverConfig::line_search_steps`].
pub const MAX_LINE_SEARCH_STEPS: u32 = 16;
/// Upper bound on the PCG iterations of [`Strategy::Frozen`] and [`Strategy::FactorOnce`].
pub const MAX_PCG_ITERATIONS: u32 = 1000;

/// How each Newton step solves its linear system.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Strategy {
    /// Refactor the positive definite Hessian at every Newton step and solve exactly.
    Refactor,
    /// Factor one positive definite matrix per topology (the Hessian at the frame-0 state) and
    /// run a fixed number of preconditioned conjugate gradient steps with it on each Newton
    /// step.
    Frozen {
        /// PCG iterations per Newton step.
        pcg_iterations: u32,
    },
    /// Refactor the positive definite Hessian at the first Newton step of each frame and solve
    /// exactly; the later Newton steps of the frame run a fixed number of preconditioned
    /// conjugate gradient steps on their own Hessian, preconditioned with that factor. One
    /// factorization per frame: the factor is at most a frame's Newton steps old, where the
    /// frozen one can be a whole deformation away.
    FactorOnce {
        /// PCG iterations per Newton step after the first.
        pcg_iterations: u32,
    },
    /// Factor one positive definite matrix per topology, as [`Strategy::Frozen`] does, and take
    /// limited-memory BFGS steps whose initial inverse Hessian is that factor: the step is
    /// `−H ∇E`, `H` the frozen matrix's inverse corrected by the last [`SECANT_PAIRS`] steps
    /// and the gradient changes they made (the two-loop recursion around one solve with the
    /// factor; Liu, Bouaziz and Kavan 2017 do the same with a rest-shape matrix), its length
    /// set by the line search. No tangent is assembled after the frozen one, so a step costs a
    /// gradient assembly, a solve pair and `4 ·` [`SECANT_PAIRS`] vector operations. The
    /// pairs are kept across frames (a frame's energy differs from the last one's by its
    /// observations, its curvature hardly), so one step per frame still uses five; they are
    /// forgotten with the frozen factor (a cut, a new embedding, a change of strategy). The step
    /// is a descent direction whatever the state (only pairs with `sᵀy > 0` are kept, so `H`
    /// stays positive definite), so the line search never lets the energy rise. Where the
    /// object turns far from the frozen state (the bands, pulled and twisted), the frozen
    /// matrix is a poor guess and `Frozen` with PCG, which applies the current Hessian,
    /// converges much faster; on the liver it is the cheapest accurate setting.
    QuasiNewton,
}

impl Strategy {
    /// Whether this core was built with the strategy (features `refactor`, `frozen`,
    /// `factor-once`, `quasi-newton`).
    pub const fn is_built(&self) -> bool {
        match self {
            Strategy::Refactor => cfg!(feature = "refactor"),
            Strategy::Frozen { .. } => cfg!(feature = "frozen"),
            Strategy::FactorOnce { .. } => cfg!(feature = "factor-once"),
            Strategy::QuasiNewton => cfg!(feature = "quasi-newton"),
        }
    }

    /// Whether the strategy keeps one factor per topology (the frozen matrix), factored when
    /// the features are embedded and after each cut: `Frozen` and `QuasiNewton`, where built.
    pub const fn freezes(&self) -> bool {
        match self {
            Strategy::Frozen { .. } => cfg!(feature = "frozen"),
            Strategy::QuasiNewton => cfg!(feature = "quasi-newton"),
            Strategy::Refactor | Strategy::FactorOnce { .. } => false,
        }
    }

    /// Whether a Newton step assembles the Hessian: every strategy's but `QuasiNewton`'s,
    /// which only solves with the frozen factor.
    pub const fn assembles_hessian(&self) -> bool {
        !matches!(self, Strategy::QuasiNewton)
    }

    /// PCG iterations per Newton step, if the strategy runs any.
    pub const fn pcg_iterations(&self) -> Option<u32> {
        match *self {
            Strategy::Refactor | Strategy::QuasiNewton => None,
            Strategy::Frozen { pcg_iterations } | Strategy::FactorOnce { pcg_iterations } => {
                Some(pcg_iterations)
            }
        }
    }
}

/// Parameters of the per-frame solve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolverConfig<T> {
    /// The linear strategy.
    pub strategy: Strategy,
    /// Newton steps per frame (fixed: no convergence test).
    pub newton_iterations: u32,
    /// Trial step lengths `1, ½, ¼, …` evaluated per Newton step (all of them, always). With
    /// one, the last Newton step's trial is assembled (energy and gradient) and closes the
    /// frame, so a frame needs no assembly after its line search.
    pub line_search_steps: u32,
    /// Stiffness of the springs between the features and the model.
    pub coupling: Coupling<T>,
    /// Where the springs turn from quadratic to linear (Huber's loss), in feature spacings
    /// (the detector's spacing, measured when the features are embedded; positive, `∞` for
    /// quadratic springs). See [`DEFAULT_SPRING_THRESHOLD`].
    pub spring_threshold: T,
    /// Damping toward the previous frame, as a fraction of each node's rest stiffness
    /// (dimensionless, `≥ 0`).
    pub damping: T,
    /// Prior on depth: stiffness against each node's displacement along the optical axis (its
    /// change of depth), as a fraction of its rest stiffness (dimensionless, `≥ 0`; 0 switches
    /// it off).
    pub depth_prior: T,
    /// Observations farther than this outside the image are rejected, pixels.
    pub image_margin: T,
}

impl<T: Real> SolverConfig<T> {
    /// The same settings in another scalar type (each value rounded to it).
    pub fn cast<U: Real>(&self) -> SolverConfig<U> {
        let c = |x: T| U::of(x.to_f64());
        SolverConfig {
            strategy: self.strategy,
            newton_iterations: self.newton_iterations,
            line_search_steps: self.line_search_steps,
            coupling: match self.coupling {
                Coupling::Relative(beta) => Coupling::Relative(c(beta)),
                Coupling::Stiffness(k) => Coupling::Stiffness(c(k)),
            },
            spring_threshold: c(self.spring_threshold),
            damping: c(self.damping),
            depth_prior: c(self.depth_prior),
            image_margin: c(self.image_margin),
        }
    }

    /// Checks the ranges.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming the first parameter out of range.
    pub fn validate(&self) -> Result<(), Error> {
        let pcg_ok = self
            .strategy
            .pcg_iterations()
            .is_none_or(|k| (1..=MAX_PCG_ITERATIONS).contains(&k));
        for (parameter, ok) in [
            (Parameter::Strategy, self.strategy.is_built()),
            (
                Parameter::NewtonIterations,
                (1..=MAX_NEWTON_ITERATIONS).contains(&self.newton_iterations),
            ),
            (
                Parameter::LineSearchSteps,
                (1..=MAX_LINE_SEARCH_STEPS).contains(&self.line_search_steps),
            ),
            (Parameter::PcgIterations, pcg_ok),
        ] {
            if !ok {
                return Err(Error::InvalidParameter { parameter });
            }
        }
        if !self.coupling.is_valid() {
            return Err(Error::InvalidParameter {
                parameter: Parameter::SpringStiffness,
            });
        }
        // `!(x > 0)` refuses NaN as well; `∞` is allowed.
        if !(self.spring_threshold > T::zero()) {
            return Err(Error::InvalidParameter {
                parameter: Parameter::SpringThreshold,
            });
        }
        if !(self.damping.finite() && self.damping >= T::zero()) {
            return Err(Error::InvalidParameter {
                parameter: Parameter::Damping,
            });
        }
        if !(self.depth_prior.finite() && self.depth_prior >= T::zero()) {
            return Err(Error::InvalidParameter {
                parameter: Parameter::DepthPrior,
            });
        }
        if !(self.image_margin.finite() && self.image_margin >= T::zero()) {
            return Err(Error::InvalidParameter {
                parameter: Parameter::ImageMargin,
            });
        }
        Ok(())
    }
}

/// The parts of the energy, joules (the spring part in the units of `k`·px²).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Energies<T> {
    /// Elastic energy `W_I`, joules.
    pub elastic: T,
    /// Spring energy `W_S`, joules (`k` in J/px² times px²).
    pub spring: T,
    /// Damping energy `W_D`, joules.
    pub damping: T,
    /// Depth prior energy `W_R`, joules.
    pub depth: T,
    /// An estimate of the rounding error of the total: node positions are only known to
    /// `ε·|x|`, so each energy term is uncertain by its local force times that (filled by the
    /// assembly, zero from an energy-only evaluation). The line search cannot see decreases
    /// below it.
    pub rounding: T,
}

impl<T: Real> Energies<T> {
    /// `W_I + W_S + W_D`.
    pub fn total(&self) -> T {
        self.elastic + self.spring + self.damping + self.depth
    }
}

/// Work done, counted in data-independent units, per stage of a frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct WorkCount {
    /// Assemblies of gradient (and Hessian).
    pub assemblies: u32,
    /// Element evaluations with a tangent (assembly).
    pub element_tangents: u64,
    /// Element evaluations without a tangent (gradient only, or energy in the line search).
    pub element_evaluations: u64,
    /// Feature spring evaluations.
    pub feature_evaluations: u64,
    /// Numeric factorizations.
    pub factorizations: u32,
    /// Multiply-adds of the factorizations.
    pub factor_flops: u64,
    /// Triangular solve pairs (forward + diagonal + backward).
    pub solves: u32,
    /// Multiply-adds of the solves.
    pub solve_flops: u64,
    /// Sparse matrix–vector products (PCG).
    pub matvecs: u32,
    /// Multiply-adds of the matrix–vector products.
    pub matvec_flops: u64,
    /// Energy evaluations of the line search.
    pub energy_evaluations: u32,
    /// Entries copied aside so that a failing frame can give the model back as it was (the
    /// features' observations and the damping reference, see [`crate::Model::step`]).
    pub state_copies: u64,
    /// Multiply-adds of the quasi-Newton strategy's secant pairs: the two-loop recursion of
    /// each step and the storing of each pair ([`Strategy::QuasiNewton`]).
    pub secant_flops: u64,
}

/// Dot product.
pub(crate) fn dot<T: Real>(a: &[T], b: &[T]) -> T {
    a.iter().zip(b).fold(T::zero(), |s, (&x, &y)| s + x * y)
}

// The unit tests compute in `f64`: an `f32`-only build has none.
#[cfg(all(test, feature = "f64"))]
mod tests {
    use super::*;

    fn config(strategy: Strategy) -> SolverConfig<f64> {
        SolverConfig {
            strategy,
            newton_iterations: 2,
            line_search_steps: 3,
            coupling: Coupling::Stiffness(1e-4),
            spring_threshold: DEFAULT_SPRING_THRESHOLD,
            damping: 0.01,
            depth_prior: 0.0,
            image_margin: 50.0,
        }
    }

    /// Every strategy is accepted exactly when it is built; one left out of the build is
    /// refused naming the strategy (CI runs this in a build with one strategy only).
    #[test]
    fn strategy_is_accepted_exactly_when_built() {
        for (strategy, built) in [
            (Strategy::Refactor, cfg!(feature = "refactor")),
            (
                Strategy::Frozen { pcg_iterations: 4 },
                cfg!(feature = "frozen"),
            ),
            (
                Strategy::FactorOnce { pcg_iterations: 4 },
                cfg!(feature = "factor-once"),
            ),
            (Strategy::QuasiNewton, cfg!(feature = "quasi-newton")),
        ] {
            assert_eq!(strategy.is_built(), built);
            let result = config(strategy).validate();
            if built {
                assert_eq!(result, Ok(()));
            } else {
                assert_eq!(
                    result,
                    Err(Error::InvalidParameter {
                        parameter: Parameter::Strategy
                    })
                );
            }
        }
    }
}
