//! Detecting a cut from motion discontinuities (paper §2.2 and §2.3).
//!
//! While the model follows the real object, the residual `d_i = f_i − P(f_iᵛ)` of each feature
//! varies smoothly over the image. Where the real object is cut and the model is not, features
//! on the two lips pull the model in different directions and neighbouring residuals stop
//! agreeing. The detector measures `μ_ij = ‖d_i − d_j‖` over the neighbour pairs fixed at frame
//! 0 (features close in the image and on the model alike), flags the pairs whose `μ_ij` exceeds
//! what the frame's own statistics explain (the paper's `ε·μ̄`, made robust: see
//! [`DetectionConfig::outlier_sigmas`]), and, once a pair has been flagged for a few frames in
//! a row, records it as split: the midpoints of split pairs are the separation points the cut
//! line is fitted to ([`crate::cutline`]).
//!
//! A temporal filter keeps tracker failures out: a feature whose residual jumps from one frame
//! to the next far more than the others' (the paper's `E_i > ε_t·Ē`, made robust the same way)
//! while none of its neighbours jumped with it is taken out of detection for good, with all its
//! pairs. A lip of a cut opening under the camera jumps as a whole: its features stay.
//!
//! Cost per frame: bounded by [`DetectionWork::bound`] in the capacities.

use crate::error::Error;
use crate::error::Parameter;
use crate::real::Real;

/// Parameters of the detection and of the cut line.
///
/// Nothing here is in pixels except the optional overrides: thresholds are in robust standard
/// deviations of what the detector measures in the frame itself, and lengths in feature spacings
/// (the side of the square each feature covers at frame 0, `√(area / features)`), so that one set
/// of defaults serves a close band and a wide liver, 300 features or 1000, 0.3 px of noise or 2.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DetectionConfig<T> {
    /// Whether detection runs at all (a scene can switch it off at run time; the `cut` feature
    /// removes it from the build).
    pub enabled: bool,
    /// Neighbour radius `r` in pixels; 0 derives it from the features' density at frame 0
    /// ([`DetectionConfig::radius_spacings`] feature spacings).
    pub radius_px: T,
    /// Neighbour radius in feature spacings when `radius_px` is 0: 2.5 gives each feature about
    /// twenty neighbours (π·2.5²), enough for its robust statistics.
    pub radius_spacings: T,
    /// Two features close in the image are not paired when, on the model at frame 0, they lie
    /// farther apart than this multiple of their image distance taken back to their depth
    /// (`‖X_i − X_j‖ > ratio · ℓ_ij · z / f`): the pair then spans a fold, or a slope seen at
    /// a grazing angle, where the residuals of a coarse model jump without any cut (what made
    /// most of the false cuts on the liver family). 3 keeps every pair on a surface tilted up
    /// to 70° from the image plane (1 / cos 70.5° = 3); 0 pairs by image distance alone.
    pub max_surface_ratio: T,
    /// A pair is an outlier when its residual difference `μ_ij` exceeds what the frame explains
    /// by this many robust standard deviations (see [`crate::detect`]).
    pub outlier_sigmas: T,
    /// A feature is a tracking failure when its residual changes from one frame to the next by
    /// more than the median change plus this many robust standard deviations of the changes,
    /// and no neighbour's changed as much and alike (within the same limit).
    /// Infinite turns the temporal filter off (what a build without the `temporal-filter`
    /// feature always does).
    pub temporal_sigmas: T,
    /// Differences below this many pixels are never outliers: the floor for scenes without
    /// noise, where the robust deviation is near zero (a tracker localises to a few tenths of a
    /// pixel at best).
    pub min_difference_px: T,
    /// Frames in a row a pair must be an outlier before it counts as split.
    pub persistence: u32,
    /// Separation points needed to start the cut line: points near the line whose pairs open
    /// across it, of which at least two leave out any one feature (so never fewer than
    /// three; see `CutLine::update`).
    pub init_points: u32,
    /// Angular restriction `α` of a front's advance, degrees.
    pub alpha_degrees: T,
    /// Shortest advance of a front, feature spacings.
    pub min_step: T,
    /// Longest advance of a front, feature spacings.
    pub max_step: T,
    /// Separation points ahead of a front needed to advance it.
    pub min_support: u32,
    /// Separation points within this distance of a candidate line count for it when the line
    /// is started (a robust fit), feature spacings.
    pub line_tolerance: T,
    /// Count only pairs whose residuals diverge across the line joining them (the lips of an
    /// opening cut), not those that converge or shear.
    pub opening_only: bool,
    /// A feature whose measured pairs are outliers in more than this fraction is taken as a
    /// tracking failure in that frame, not as evidence of a cut (a cut separates a feature
    /// from the neighbours on the far side only).
    pub max_outlier_fraction: T,
    /// Direction the cut line is extruded along into the model (world); `None` uses the
    /// camera's viewing direction.
    pub depth: Option<[T; 3]>,
}

impl<T: Real> DetectionConfig<T> {
    /// The defaults, calibrated by the data of each frame (why each value is what it is:
    /// the README's "Cut detection" section and the field docs).
    pub fn paper() -> Self {
        DetectionConfig {
            enabled: true,
            radius_px: T::zero(),
            radius_spacings: T::of(2.5),
            max_surface_ratio: T::of(3.0),
            outlier_sigmas: T::of(OUTLIER_SIGMAS),
            temporal_sigmas: T::of(TEMPORAL_SIGMAS),
            min_difference_px: T::of(0.5),
            persistence: 2,
            init_points: 6,
            alpha_degrees: T::of(35.0),
            min_step: T::of(0.1),
            max_step: T::of(1.0),
            min_support: 3,
            line_tolerance: T::of(0.3),
            max_outlier_fraction: T::of(0.85),
            opening_only: true,
            depth: None,
        }
    }

    /// The same settings in another scalar type (each value rounded to it).
    pub fn cast<U: Real>(&self) -> DetectionConfig<U> {
        let c = |x: T| U::of(x.to_f64());
        DetectionConfig {
            enabled: self.enabled,
            radius_px: c(self.radius_px),
            radius_spacings: c(self.radius_spacings),
            max_surface_ratio: c(self.max_surface_ratio),
            outlier_sigmas: c(self.outlier_sigmas),
            temporal_sigmas: c(self.temporal_sigmas),
            min_difference_px: c(self.min_difference_px),
            persistence: self.persistence,
            init_points: self.init_points,
            alpha_degrees: c(self.alpha_degrees),
            min_step: c(self.min_step),
            max_step: c(self.max_step),
            min_support: self.min_support,
            line_tolerance: c(self.line_tolerance),
            max_outlier_fraction: c(self.max_outlier_fraction),
            opening_only: self.opening_only,
            depth: self.depth.map(|d| d.map(c)),
        }
    }

    /// Checks the ranges, field by field in declaration order (`max_step` before `min_step`,
    /// which must not exceed it).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] naming the first field out of its range
    /// ([`Parameter::RadiusPx`] … [`Parameter::Depth`]).
    pub fn validate(&self) -> Result<(), Error> {
        let pos = |x: T| x.finite() && x > T::zero();
        let checks = [
            (
                Parameter::RadiusPx,
                self.radius_px.finite() && self.radius_px >= T::zero(),
            ),
            (Parameter::RadiusSpacings, pos(self.radius_spacings)),
            (
                Parameter::MaxSurfaceRatio,
                self.max_surface_ratio.finite()
                    && (self.max_surface_ratio == T::zero() || self.max_surface_ratio >= T::one()),
            ),
            (Parameter::OutlierSigmas, pos(self.outlier_sigmas)),
            (
                Parameter::TemporalSigmas,
                self.temporal_sigmas > T::zero(), // +∞ included: the filter off
            ),
            (
                Parameter::MinDifferencePx,
                self.min_difference_px.finite() && self.min_difference_px >= T::zero(),
            ),
            (
                Parameter::Persistence,
                self.persistence >= 1 && self.persistence < 255,
            ),
            (Parameter::InitPoints, self.init_points >= 2),
            (
                Parameter::AlphaDegrees,
                self.alpha_degrees.finite()
                    && self.alpha_degrees > T::zero()
                    && self.alpha_degrees <= T::of(90.0),
            ),
            (Parameter::MaxStep, pos(self.max_step)),
            (
                Parameter::MinStep,
                self.min_step.finite()
                    && self.min_step >= T::zero()
                    && self.min_step <= self.max_step,
            ),
            (Parameter::MinSupport, self.min_support >= 1),
            (Parameter::LineTolerance, pos(self.line_tolerance)),
            (
                Parameter::MaxOutlierFraction,
                pos(self.max_outlier_fraction),
            ),
            (
                Parameter::Depth,
                self.depth.is_none_or(|d| {
                    d.iter().all(|c| c.finite()) && d.iter().any(|c| *c != T::zero())
                }),
            ),
        ];
        match checks.iter().find(|(_, ok)| !ok) {
            Some(&(parameter, _)) => Err(Error::InvalidParameter { parameter }),
            None => Ok(()),
        }
    }
}

/// Default [`DetectionConfig::outlier_sigmas`].
pub const OUTLIER_SIGMAS: f64 = 6.0;
/// Default [`DetectionConfig::temporal_sigmas`].
pub const TEMPORAL_SIGMAS: f64 = 10.0;

/// What the outlier test read of one neighbour pair in a frame
/// ([`Detector::pair_measure`]), pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PairMeasure<T> {
    /// The residual difference `μ_ij = ‖d_i − d_j‖`.
    pub difference: T,
    /// The pair's length in the image `ℓ_ij` (between the tracked features).
    pub length: T,
    /// What the smooth field explains over it, `min(sᵢ, sⱼ) · ℓ_ij` (each feature's lower
    /// tertile of its pairs' slopes `μ / ℓ`).
    pub smooth: T,
}

/// What the detector saw in one frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DetectionReport<T> {
    /// Neighbour pairs built at frame 0.
    pub pairs: usize,
    /// Pairs measured this frame (both features observed and neither filtered out).
    pub pairs_active: usize,
    /// Pairs dropped so far because a feature was filtered out.
    pub pairs_lost: usize,
    /// Pairs whose `μ_ij` exceeded its threshold this frame.
    pub outliers: usize,
    /// Pairs counted as split this frame (outliers for `persistence` frames in a row).
    pub split: usize,
    /// Features taken out by the temporal filter so far.
    pub features_filtered: usize,
    /// Median `μ` over the active pairs, pixels.
    pub median_difference_px: T,
    /// Robust standard deviation of `μ` over the active pairs (1.4826 × MAD), pixels.
    pub deviation_px: T,
    /// Separation points this frame.
    pub separation_points: usize,
    /// Work done this frame.
    pub work: DetectionWork,
}

/// Work of the detector in one frame, counted in data-independent units; bounded by
/// [`DetectionWork::bound`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DetectionWork {
    /// Feature visits (temporal filter, per-feature statistics).
    pub feature_visits: u64,
    /// Pair visits (the temporal filter's pairs, differences, slopes, the walk in order of
    /// slope, thresholds, persistence).
    pub pair_visits: u64,
    /// Steps of the robust statistics: the selections' ([`crate::robust::select_rounded`]:
    /// comparisons of its rank count or heap on few values, visits of its radix passes on
    /// many) and the sort of the pairs' slopes ([`crate::robust::radix_order`]).
    pub selection_steps: u64,
}

impl DetectionWork {
    /// The most work of one frame with `features` feature slots and `pairs` pairs:
    /// - feature visits `7 n`: the temporal filter's four passes (two without filtering), the
    ///   per-feature tertiles' two (the counts reset; the ranks set and the slopes cleared),
    ///   and the outlier counts' reset;
    /// - pair visits `7 P`: the temporal filter's pairs, the pairs dropped for a newly
    ///   filtered end (in the frames that filter one), the differences, the pairs' slopes,
    ///   the walk in order of slope, outliers, persistence;
    /// - selection steps: the median and MAD of the changes (`2 S(n)`) and of the differences
    ///   (`2 S(P)`), with `S(m)` the most steps of one selection among at most `m` values
    ///   ([`crate::robust::select_bound_up_to`]: the slots in use, however few), and the pairs
    ///   ordered by slope ([`crate::robust::radix_order_steps`]`(P)`).
    pub const fn bound(features: u64, pairs: u64) -> DetectionWork {
        use crate::robust::{radix_order_steps, select_bound_up_to};
        DetectionWork {
            feature_visits: 7 * features,
            pair_visits: 7 * pairs,
            selection_steps: 2 * select_bound_up_to(features)
                + 2 * select_bound_up_to(pairs)
                + radix_order_steps(pairs),
        }
    }

    /// Whether every count is at most `other`'s.
    pub fn within(&self, other: &DetectionWork) -> bool {
        self.feature_visits <= other.feature_visits
            && self.pair_visits <= other.pair_visits
            && self.selection_steps <= other.selection_steps
    }
}

#[cfg(feature = "detect")]
pub use detector::{Detector, GRID_CELLS, SplitPairs};

#[cfg(feature = "detect")]
mod detector;
