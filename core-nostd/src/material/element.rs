//! The geometry of one linear tetrahedron: its checked rest shape and the gradients that map
//! node displacements to the deformation gradient.

use nalgebra::{Matrix3, Vector3};

use crate::error::{Error, Resource};
use crate::real::Real;

/// Rest geometry of one linear tetrahedron, checked once so that the per-frame element
/// functions cannot fail.
///
/// Invariants after [`ElementRest::new`]: every entry is finite, `volume > 0`, and the rest
/// tetrahedron is positively oriented and not degenerate in the sense documented there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ElementRest<T> {
    /// `Dm⁻¹` (1/m), where `Dm = [X1 − X0, X2 − X0, X3 − X0]` holds the rest edge vectors from
    /// node 0 as columns.
    pub dm_inv: Matrix3<T>,
    /// Rest volume `det(Dm) / 6` (m³), positive.
    pub volume: T,
}

/// Relative degeneracy tolerance in units of machine epsilon: a rest tetrahedron with
/// `|det Dm| ≤ DEGENERACY_EPS · EPS · ℓ³` (`ℓ` its longest edge) is rejected. `4096 · EPS` is
/// `9.1e-13` for `f64` (the `1e-12` of common practice) and `4.9e-4` for `f32`: below it `Dm⁻¹`
/// carries a condition number that leaves no correct digit in the strain of the working type.
const DEGENERACY_EPS: f64 = 4096.0;

impl<T: Real> ElementRest<T> {
    /// Builds the rest geometry of the tetrahedron with node positions `x` (metres, local node
    /// order 0..3), `tet_index` being its index in the mesh (used only in errors).
    ///
    /// # Errors
    /// Checked in this order:
    /// - [`Error::NonFiniteInput`] with [`Resource::Nodes`] if a coordinate is NaN or infinite;
    ///   `position` is the slot of that node in the flattened connectivity,
    ///   `4 · tet_index + a` for local node `a` (saturating). Finite coordinates so large that
    ///   the edge vectors, `det Dm` or `Dm⁻¹` overflow are reported the same way at local node 0.
    /// - [`Error::DegenerateElement`] if `|det Dm| ≤ 4096 · EPS · ℓ³`, `ℓ` the longest of the six
    ///   edges (this includes coincident and coplanar nodes).
    /// - [`Error::InvertedElement`] if `det Dm < 0` (node 3 lies on the wrong side of the face
    ///   `0, 1, 2` for the right-hand rule).
    pub fn new(x: &[[T; 3]; 4], tet_index: usize) -> Result<Self, Error> {
        let slot = |a: usize| tet_index.saturating_mul(4).saturating_add(a);
        for (a, node) in x.iter().enumerate() {
            if !node.iter().all(|c| c.finite()) {
                return Err(Error::NonFiniteInput {
                    resource: Resource::Nodes,
                    position: slot(a),
                });
            }
        }
        let overflow = Error::NonFiniteInput {
            resource: Resource::Nodes,
            position: slot(0),
        };
        let p = nodes(x);
        let dm = Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]);
        let mut longest_sq = T::zero();
        for (a, pa) in p.iter().enumerate() {
            for pb in p.iter().skip(a + 1) {
                longest_sq = longest_sq.max((pb - pa).norm_squared());
            }
        }
        let scale = longest_sq * longest_sq.sqrt();
        let det = dm.determinant();
        if !(scale.finite() && det.finite()) {
            return Err(overflow);
        }
        if det.abs() <= T::of(DEGENERACY_EPS) * T::EPS * scale {
            return Err(Error::DegenerateElement { tet: tet_index });
        }
        if det < T::zero() {
            return Err(Error::InvertedElement { tet: tet_index });
        }
        // `det` is well away from zero here, so the inverse exists; `None` or an overflowing
        // entry can only come from extreme magnitudes.
        let dm_inv = dm.try_inverse().ok_or(overflow)?;
        let volume = det / T::of(6.0);
        if !(dm_inv.iter().all(|v| v.finite()) && volume > T::zero()) {
            return Err(overflow);
        }
        Ok(ElementRest { dm_inv, volume })
    }

    /// Constant shape-function gradients `g_a` (1/m) of the four nodes with respect to the rest
    /// coordinates: `g_k = (row k−1 of Dm⁻¹)ᵀ` for `k = 1, 2, 3` and `g_0 = −(g_1 + g_2 + g_3)`,
    /// so that `F = Σ_a x_a g_aᵀ` and `Σ_a g_a = 0`.
    pub fn shape_gradients(&self) -> [Vector3<T>; 4] {
        let r = |k: usize| self.dm_inv.row(k).transpose();
        let (g1, g2, g3) = (r(0), r(1), r(2));
        [-(g1 + g2 + g3), g1, g2, g3]
    }
}

pub(crate) fn nodes<T: Real>(x: &[[T; 3]; 4]) -> [Vector3<T>; 4] {
    x.map(|c| Vector3::new(c[0], c[1], c[2]))
}

/// Displacement gradient `H = ∂u/∂X = Σ_a u_a g_aᵀ` (dimensionless) of the tetrahedron whose
/// nodes are displaced by `u` (metres) from rest, with shape gradients `g` from
/// [`ElementRest::shape_gradients`]; the deformation gradient is `F = I + H`.
///
/// The element functions work from displacements rather than positions so that strain is
/// computed without cancellation: with positions, `F` carries an absolute rounding error of
/// `ε·|x|/h` and `E = ½(FᵀF − I)` loses the digits a small strain needs, which makes energy
/// differences (the line search) and near-converged gradients noisy. Evaluated as
/// `Σ_{k=1..3} (u_k − u_0) g_kᵀ` (equal because `Σ_a g_a = 0`), so a common translation
/// cancels first.
#[inline(always)]
pub fn displacement_gradient<T: Real>(u: &[[T; 3]; 4], g: &[Vector3<T>; 4]) -> Matrix3<T> {
    let p = nodes(u);
    (p[1] - p[0]) * g[1].transpose()
        + (p[2] - p[0]) * g[2].transpose()
        + (p[3] - p[0]) * g[3].transpose()
}

/// Deformation gradient `F = I + H` for displacements `u`, see [`displacement_gradient`].
pub fn deformation_gradient<T: Real>(u: &[[T; 3]; 4], g: &[Vector3<T>; 4]) -> Matrix3<T> {
    Matrix3::identity() + displacement_gradient(u, g)
}
