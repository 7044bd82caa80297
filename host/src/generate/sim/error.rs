//! Why a simulation step fails.

use std::fmt;

use incise_core::Error as CoreError;

// For the documentation's links only.
#[cfg(doc)]
use super::{MAX_HALVINGS, MAX_SUBSTEPS, Simulator};

/// Why a sub-step failed; carried by [`SimError::NotConverged`] for the last failure.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Failure {
    /// Newton used its `max_iter` iterations without meeting the tolerance.
    IterationLimit,
    /// No trial step of the line search was acceptable (or the Newton direction was not a
    /// descent direction).
    LineSearchStalled,
    /// Moving the prescribed nodes inverted an element, with and without the predictor.
    InvertedStart,
    /// The regularised Hessian could not be factorized.
    Factorization,
}

impl fmt::Display for Failure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Failure::IterationLimit => "iteration limit reached",
            Failure::LineSearchStalled => "line search stalled",
            Failure::InvertedStart => "moving the prescribed nodes inverts an element",
            Failure::Factorization => "the Hessian could not be factorized",
        })
    }
}

/// Errors of [`Simulator::new`] and [`Simulator::solve`].
///
/// `PartialEq` but not `Eq`: [`SimError::NotConverged`] carries floating-point diagnostics.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SimError {
    /// From the core: bad material parameters, a non-finite, degenerate or inverted rest
    /// tetrahedron (named by index), or a failure of the sparse pipeline.
    Core(CoreError),
    /// A tetrahedron or the prescribed list names node `node`, but there are only `nodes`.
    NodeOutOfRange {
        /// The offending index.
        node: u32,
        /// Number of nodes.
        nodes: usize,
    },
    /// Node `node` is listed twice in the prescribed nodes.
    DuplicatePrescribed {
        /// The repeated node.
        node: u32,
    },
    /// Every node is prescribed: there is nothing to solve for.
    NoFreeNodes,
    /// `targets` must have one entry per prescribed node.
    TargetCount {
        /// Number of prescribed nodes.
        expected: usize,
        /// Length of `targets`.
        got: usize,
    },
    /// `targets[index]` has a NaN or infinite coordinate.
    NonFiniteTarget {
        /// Position in `targets`.
        index: usize,
    },
    /// The frame could not be solved within [`MAX_HALVINGS`] sub-step halvings (or
    /// [`MAX_SUBSTEPS`] sub-steps). The simulator is left in its state before the call.
    NotConverged {
        /// Fraction of the frame's prescribed increment that had been reached, in `[0, 1)`.
        reached: f64,
        /// Newton iterations spent in the call.
        iterations: usize,
        /// `‖∇W‖∞` (N) over the free nodes when the last sub-step gave up.
        gradient_norm: f64,
        /// Why the last attempted sub-step failed.
        cause: Failure,
    },
    /// A NaN or infinity appeared in the gradient of a feasible state (should not happen: the
    /// element functions guard against it). The simulator is left in its state before the
    /// call.
    NotFinite,
    /// [`Simulator::set_displacements`] was given `got` displacements for `expected` nodes.
    StateLength {
        /// Number of nodes.
        expected: usize,
        /// Length of the given state.
        got: usize,
    },
    /// [`Simulator::set_displacements`] was given a state that is not finite or inverts an
    /// element.
    InfeasibleState,
}

impl From<CoreError> for SimError {
    fn from(e: CoreError) -> Self {
        SimError::Core(e)
    }
}

impl fmt::Display for SimError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SimError::Core(e) => write!(f, "{e}"),
            SimError::NodeOutOfRange { node, nodes } => {
                write!(f, "node {node} out of range (the mesh has {nodes} nodes)")
            }
            SimError::DuplicatePrescribed { node } => {
                write!(f, "node {node} is prescribed twice")
            }
            SimError::NoFreeNodes => f.write_str("every node is prescribed"),
            SimError::TargetCount { expected, got } => {
                write!(f, "{got} targets given for {expected} prescribed nodes")
            }
            SimError::NonFiniteTarget { index } => write!(f, "target {index} is not finite"),
            SimError::NotConverged {
                reached,
                iterations,
                gradient_norm,
                cause,
            } => write!(
                f,
                "quasi-static solve did not converge ({cause}) after {iterations} Newton \
                 iterations, {:.1} % of the prescribed motion reached, |grad| = {gradient_norm:e} N",
                100.0 * reached
            ),
            SimError::NotFinite => f.write_str("non-finite value in the elastic gradient"),
            SimError::StateLength { expected, got } => {
                write!(f, "{got} displacements given for {expected} nodes")
            }
            SimError::InfeasibleState => {
                f.write_str("the given state is not finite or inverts an element")
            }
        }
    }
}

impl std::error::Error for SimError {}
