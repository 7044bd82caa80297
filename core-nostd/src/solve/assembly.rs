//! Assembly: the energies, the gradient and the (PSD-projected) Hessian of the frame's problem
//! (elastic energy, feature springs through the camera, damping and depth prior), element by
//! element into the stiffness pattern through the scatter map.

use core::cell::Cell;

use nalgebra::{Matrix2x3, Matrix3, Vector3};

use super::{Energies, WorkCount};
use crate::camera::Camera;
use crate::embed::Embedding;
use crate::error::{Error, Resource};
use crate::features::Features;
use crate::material::{
    ElementRest, InversionBarrier, Lame, Law, PAIRS, TangentProjection, displacement_gradient,
    element_gradient_of_stress,
};
#[cfg(feature = "paired-elements")]
use crate::material::{ElementShare, svk_shares_of_two};
use crate::mesh::Mesh;
use crate::real::Real;
use crate::sparse::{NONE, UpperCsc, ux};
use crate::storage::{ensure_exact_len, ensure_len};

/// The elements' share of an assembly besides their gradient: what
/// [`Problem::assemble_keeping`] keeps for [`Problem::assemble_reusing`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct ElementSums<T> {
    /// The elastic energy (the inversion barrier's included).
    pub energy: T,
    /// The sum of the elements' force magnitudes, for the rounding estimate.
    pub force_sum: T,
}

/// Everything the assembly reads, borrowed from the model.
pub(crate) struct Problem<'p, 'a, T: Real> {
    pub mesh: &'p Mesh<'a, T>,
    /// The material's strain energy law.
    pub law: Law,
    pub lame: Lame<T>,
    /// The inversion barrier added to the elastic energy, if the material has one.
    pub barrier: Option<InversionBarrier<T>>,
    pub camera: &'p Camera<T>,
    /// The features' observations (targets, observed in this frame).
    pub features: &'p Features<'a, T>,
    /// Where each feature sits in the mesh (slot by slot).
    pub embedding: &'p Embedding<'a, T>,
    pub spring_stiffness: T,
    /// Where the springs turn linear (Huber's loss), pixels.
    pub spring_threshold_px: T,
    /// Damping weight per node.
    pub damping: &'p [T],
    /// Depth-prior weight per node.
    pub depth_weight: &'p [T],
    /// What the depth-prior weights are multiplied by (the springs' stiffness over the default
    /// coupling's, at least 1).
    pub depth_scale: T,
    /// Positions of the previous frame, which the damping pulls toward.
    pub previous: &'p [[T; 3]],
    /// The unit camera ray through each node's previous position ([`camera_rays`]): what a
    /// spring sees of a node's motion is its motion across that ray.
    pub rays: &'p [[T; 3]],
    /// What the springs see of each node at the positions of the pass under way
    /// ([`Problem::see_nodes`]): the node less its motion along its ray since the previous
    /// frame. Filled once per spring pass for every node rather than once per feature for each
    /// of its element's four; cells, so that a pass through `&self` can fill them.
    pub seen: &'p [Cell<[T; 3]>],
    /// Per tetrahedron, per node pair ([`PAIRS`]) and column, the position in the pattern's
    /// value array of the block's first row; [`NONE`] when a node of the pair is fixed.
    pub scatter: &'p [[u32; 30]],
    /// Column pointers of the stiffness pattern (the diagonal ends each column).
    pub col_ptr: &'p [u32],
}

/// Huber's loss of a spring whose residual has squared length `r2` (px²) against threshold
/// `delta` (px): `(ρ, w)` with `ρ = ½ r²` and `w = 1` up to the threshold, `ρ = δ r − ½ δ²`
/// and `w = δ / r` beyond; the spring's force is `k w r`, its Gauss–Newton weight `k w`.
fn huber<T: Real>(r2: T, delta: T) -> (T, T) {
    if r2 <= delta * delta {
        (T::of(0.5) * r2, T::one())
    } else {
        let r = r2.sqrt();
        (delta * r - T::of(0.5) * delta * delta, delta / r)
    }
}

fn vec3<T: Real>(p: &[T; 3]) -> Vector3<T> {
    Vector3::new(p[0], p[1], p[2])
}

/// The compact (free) index of each node of `tet`, [`NONE`] for a fixed node. The mesh checks
/// its tetrahedra's nodes against `free` when it is loaded or edited; a node out of range
/// would count as fixed.
#[inline]
fn free_of(free: &[u32], tet: &[u32; 4]) -> [u32; 4] {
    tet.map(|v| free.get(ux(v)).copied().unwrap_or(NONE))
}

/// The column ends `col_ptr[3 f + 1 ..= 3 f + 3]` of free node `f`'s three columns (empty if
/// out of range, which the pattern built for the mesh's free nodes never is).
fn column_ends(col_ptr: &[u32], f: u32) -> &[u32] {
    let first = 3 * ux(f) + 1;
    col_ptr.get(first..first + 3).unwrap_or_default()
}

impl<T: Real> Problem<'_, '_, T> {
    /// Displacements from rest of the nodes `tet` of tetrahedron `t`.
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] for a node beyond `x` or the rest positions.
    fn element_u(&self, t: usize, tet: &[u32; 4], x: &[[T; 3]]) -> Result<[[T; 3]; 4], Error> {
        let rest = self.mesh.rest();
        let mut u = [[T::zero(); 3]; 4];
        for (k, (ue, &v)) in u.iter_mut().zip(tet).enumerate() {
            let (Some(p), Some(q)) = (x.get(ux(v)), rest.get(ux(v))) else {
                return Err(Error::IndexOutOfRange {
                    resource: Resource::Nodes,
                    position: 4 * t + k,
                    index: ux(v),
                    bound: x.len().min(rest.len()),
                });
            };
            *ue = [p[0] - q[0], p[1] - q[1], p[2] - q[2]];
        }
        Ok(u)
    }

    fn element_rest(&self, t: usize) -> Result<ElementRest<T>, Error> {
        self.mesh.element_rest(t).ok_or(Error::IndexOutOfRange {
            resource: Resource::Tetrahedra,
            position: t,
            index: t,
            bound: self.mesh.n_tets(),
        })
    }

    /// Energy at positions `x`.
    ///
    /// # Errors
    /// [`Error::FeatureBehindCamera`] if a virtual feature cannot be projected.
    // Out of line, as `assemble`: a few calls per frame, and profilers can tell the stages apart.
    #[inline(never)]
    pub fn energy(&self, x: &[[T; 3]], work: &mut WorkCount) -> Result<Energies<T>, Error> {
        let mut e = Energies::default();
        for (t, tet) in self.mesh.tets().iter().enumerate() {
            let rest = self.element_rest(t)?;
            let g = rest.shape_gradients();
            let h = displacement_gradient(&self.element_u(t, tet, x)?, &g);
            e.elastic += self.law.element_energy_of_h(&self.lame, rest.volume, &h);
            if let Some(barrier) = &self.barrier {
                e.elastic += barrier.element_energy(rest.volume, &h);
            }
        }
        work.element_evaluations += self.mesh.n_tets() as u64;
        e.spring = self.spring_energy(x, work)?;
        e.damping = self.damping_energy(x);
        e.depth = self.depth_energy(x);
        work.energy_evaluations += 1;
        Ok(e)
    }

    /// The stiffness of the spring of a feature observed (`active` ≠ 0) or not in this frame.
    ///
    /// Every embedded feature's spring is evaluated in every pass, an unobserved one with
    /// stiffness zero (its stale target then adds exact zeros to every sum, and changes no
    /// result): so a frame's work does not depend on how many features the tracker still
    /// follows, and every frame of one topology costs the same, as the line search evaluates all
    /// its trials whatever it finds. A timing test on any frame measures the worst case.
    fn spring_weight(&self, active: u32) -> T {
        if active == 0 {
            T::zero()
        } else {
            self.spring_stiffness
        }
    }

    fn spring_energy(&self, x: &[[T; 3]], work: &mut WorkCount) -> Result<T, Error> {
        let mut sum = T::zero();
        self.see_nodes(x);
        let observations = self.features.active().iter().zip(self.features.targets());
        for (slot, (&active, target)) in observations.enumerate() {
            let (_, tet, w) = self.feature_element(slot)?;
            let (p, _) = seen_point(self.rays, self.seen, tet, w).ok_or(Error::NoFeatures)?;
            let uv = match self.camera.project(&p, slot) {
                Ok(uv) => uv,
                // Not observed: nothing pulls it, wherever it is.
                Err(_) if active == 0 => continue,
                Err(_) => return Err(self.features.behind_camera(slot)),
            };
            let (du, dv) = (target[0] - uv.x, target[1] - uv.y);
            sum +=
                self.spring_weight(active) * huber(du * du + dv * dv, self.spring_threshold_px).0;
            work.feature_evaluations += 1;
        }
        Ok(sum)
    }

    /// The tetrahedron (index and nodes) and the barycentric weights of the feature in `slot`;
    /// [`Error::NoFeatures`] where [`Embedding::position`] would fail.
    fn feature_element(&self, slot: usize) -> Result<(usize, &[u32; 4], &[T; 4]), Error> {
        let (Some(&t), Some(w)) = (
            self.embedding.tets().get(slot),
            self.embedding.weights().get(slot),
        ) else {
            return Err(Error::NoFeatures);
        };
        let tet = self.mesh.tets().get(ux(t)).ok_or(Error::NoFeatures)?;
        Ok((ux(t), tet, w))
    }

    /// Fills [`Problem::seen`] for positions `x`: each node `y_a = x_a − e_a (e_a · (x_a −
    /// x_a⁻))`, as many as `seen`, the rays, `x` and the previous positions all hold (the
    /// mesh's nodes).
    fn see_nodes(&self, x: &[[T; 3]]) {
        let nodes = self
            .seen
            .iter()
            .zip(self.rays)
            .zip(x.iter().zip(self.previous));
        for ((cell, ray), (now, before)) in nodes {
            let (now, ray) = (vec3(now), vec3(ray));
            let y = now - ray * ray.dot(&(now - vec3(before)));
            cell.set([y.x, y.y, y.z]);
        }
    }

    fn depth_energy(&self, x: &[[T; 3]]) -> T {
        let rest = self.mesh.rest();
        let mut sum = T::zero();
        let axis = self.camera.view_direction();
        // `x` and the weights hold at least the `n_nodes()` nodes of `rest()`.
        let nodes = self.depth_weight.iter().zip(x).zip(rest);
        for ((&c, p), q) in nodes.take(self.mesh.n_nodes()) {
            if c == T::zero() {
                continue;
            }
            let c = c * self.depth_scale;
            let s = (vec3(p) - vec3(q)).dot(&axis);
            sum += T::of(0.5) * c * s * s;
        }
        sum
    }

    fn damping_energy(&self, x: &[[T; 3]]) -> T {
        let mut sum = T::zero();
        // `x`, the weights and the previous positions hold at least the `n_nodes()` nodes.
        let nodes = self.damping.iter().zip(x).zip(self.previous);
        for ((&c, p), q) in nodes.take(self.mesh.n_nodes()) {
            let d = vec3(p) - vec3(q);
            sum += T::of(0.5) * c * d.norm_squared();
        }
        sum
    }

    /// Gradient over the free unknowns into `grad` (`3 · n_free`), and, when `hessian` is
    /// given, the positive definite Hessian into the pattern's values; returns the energy.
    ///
    /// # Errors
    /// [`Error::FeatureBehindCamera`] if a virtual feature cannot be projected.
    // Out of line (a few calls per frame) so that profilers can tell assembly from the Newton
    // loop around it.
    #[inline(never)]
    pub fn assemble(
        &self,
        x: &[[T; 3]],
        grad: &mut [T],
        mut hessian: Option<&mut [T]>,
        work: &mut WorkCount,
    ) -> Result<Energies<T>, Error> {
        let elements = self.assemble_elements(x, grad, hessian.as_deref_mut(), work)?;
        self.assemble_springs_and_priors(x, grad, hessian, elements, work)
    }

    /// As [`Problem::assemble`], and the elements' share of it kept: their gradient in `kept`
    /// (as long as `grad`) and their sums in `kept_sums`, for [`Problem::assemble_reusing`] at
    /// the same positions.
    ///
    /// # Errors
    /// As [`Problem::assemble`]; [`Error::Length`] if `kept` is not as long as `grad`.
    #[inline(never)]
    pub fn assemble_keeping(
        &self,
        x: &[[T; 3]],
        grad: &mut [T],
        mut hessian: Option<&mut [T]>,
        kept: &mut [T],
        kept_sums: &mut ElementSums<T>,
        work: &mut WorkCount,
    ) -> Result<Energies<T>, Error> {
        ensure_exact_len(kept, grad.len(), Resource::Unknowns)?;
        let elements = self.assemble_elements(x, grad, hessian.as_deref_mut(), work)?;
        kept.copy_from_slice(grad);
        *kept_sums = elements;
        self.assemble_springs_and_priors(x, grad, hessian, elements, work)
    }

    /// The gradient and energies of [`Problem::assemble`] without the Hessian where the
    /// elements' share at these positions is known already (`kept` and `sums`, from
    /// [`Problem::assemble_keeping`] at the same positions of the same mesh): only the springs,
    /// the damping and the depth prior are evaluated. The elements' share depends on the
    /// positions alone and comes first in the sums, so the result is the assembly's, bit for
    /// bit (when it was kept from an assembly without the Hessian; with it, its element
    /// kernel rounds otherwise).
    ///
    /// # Errors
    /// As [`Problem::assemble`]; [`Error::Length`] if `kept` is not as long as `grad`.
    #[inline(never)]
    pub fn assemble_reusing(
        &self,
        x: &[[T; 3]],
        grad: &mut [T],
        kept: &[T],
        sums: ElementSums<T>,
        work: &mut WorkCount,
    ) -> Result<Energies<T>, Error> {
        ensure_exact_len(kept, grad.len(), Resource::Unknowns)?;
        grad.copy_from_slice(kept);
        self.assemble_springs_and_priors(x, grad, None, sums, work)
    }

    /// The elements' share of an assembly: `grad` (and the Hessian's values, when given) set
    /// to it.
    fn assemble_elements(
        &self,
        x: &[[T; 3]],
        grad: &mut [T],
        mut hessian: Option<&mut [T]>,
        work: &mut WorkCount,
    ) -> Result<ElementSums<T>, Error> {
        let free = self.mesh.free_index();
        grad.fill(T::zero());
        if let Some(h) = hessian.as_deref_mut() {
            h.fill(T::zero());
        }
        let mut e = Energies::default();
        let mut force_sum = T::zero();
        let tets = self.mesh.tets();
        // A gradient of SVK elements goes two elements at a time (the same values bit for
        // bit, see `material::paired`), the last one of an odd count as a tangent does. Built
        // with the `paired-elements` feature (the host's; a firmware build at opt-level "s"
        // leaves it out, where the compiler does not pack the lanes and it only adds code).
        #[allow(unused_mut)]
        let mut paired = 0;
        #[cfg(feature = "paired-elements")]
        if hessian.is_none() && self.law == Law::SaintVenantKirchhoff {
            let (twos, _) = tets.as_chunks::<2>();
            for (k, two) in twos.iter().enumerate() {
                let t = 2 * k;
                let (rest_a, u_a) = (self.element_rest(t)?, self.element_u(t, &two[0], x)?);
                let (rest_b, u_b) = (
                    self.element_rest(t + 1)?,
                    self.element_u(t + 1, &two[1], x)?,
                );
                let shares = svk_shares_of_two(
                    &self.lame,
                    self.barrier.as_ref(),
                    [&rest_a, &rest_b],
                    [&u_a, &u_b],
                );
                for (tet, share) in two.iter().zip(shares) {
                    let ElementShare {
                        energy,
                        barrier_energy,
                        gradient,
                    } = share;
                    e.elastic += energy;
                    if let Some(energy) = barrier_energy {
                        e.elastic += energy;
                    }
                    for (ga, &f) in gradient.iter().zip(&free_of(free, tet)) {
                        add_gradient(grad, f, ga);
                        force_sum += ga.abs().sum();
                    }
                }
            }
            paired = 2 * twos.len();
        }
        for (t, tet) in tets.iter().enumerate().skip(paired) {
            let rest = self.element_rest(t)?;
            let g = rest.shape_gradients();
            let du = displacement_gradient(&self.element_u(t, tet, x)?, &g);
            let ft = free_of(free, tet);
            let gradient = match hessian.as_deref_mut() {
                Some(h) => {
                    let mut eval = self.law.element_eval_upper_of_h(
                        &self.lame,
                        rest.volume,
                        &g,
                        &du,
                        TangentProjection::PositiveDefinite,
                    );
                    if let Some(barrier) = &self.barrier {
                        barrier.add_upper_tangent(
                            rest.volume,
                            &g,
                            &du,
                            TangentProjection::PositiveDefinite,
                            &mut eval,
                        );
                    }
                    e.elastic += eval.energy;
                    let scatter = self.scatter.get(t).ok_or(Error::SymbolicMismatch)?;
                    let blocks = eval.blocks.iter().zip(scatter.as_chunks::<3>().0);
                    for (&(a, b), (m, starts)) in PAIRS.iter().zip(blocks) {
                        // `a`, `b` < 4 (the pairs of a tetrahedron's nodes).
                        if let (Some(&fa), Some(&fb)) = (ft.get(a), ft.get(b)) {
                            add_block(h, starts, a == b, fa >= fb, m);
                        }
                    }
                    eval.gradient
                }
                None => {
                    // The barrier's stress joins the law's before the nodes' gradient is
                    // formed: one product with the shape gradients, where adding the two
                    // gradients took two.
                    let (energy, mut stress) =
                        self.law
                            .element_energy_stress_of_h(&self.lame, rest.volume, &du);
                    e.elastic += energy;
                    if let Some(barrier) = &self.barrier {
                        barrier.add_element_stress(rest.volume, &du, &mut e.elastic, &mut stress);
                    }
                    element_gradient_of_stress(rest.volume, &stress, &g)
                }
            };
            for (ga, &f) in gradient.iter().zip(&ft) {
                add_gradient(grad, f, ga);
                force_sum += ga.abs().sum();
            }
        }
        if hessian.is_some() {
            work.element_tangents += self.mesh.n_tets() as u64;
        } else {
            work.element_evaluations += self.mesh.n_tets() as u64;
        }
        Ok(ElementSums {
            energy: e.elastic,
            force_sum,
        })
    }

    /// The rest of an assembly, added to the elements' share in `grad` (and the Hessian):
    /// the springs, the damping and the depth prior.
    fn assemble_springs_and_priors(
        &self,
        x: &[[T; 3]],
        grad: &mut [T],
        mut hessian: Option<&mut [T]>,
        elements: ElementSums<T>,
        work: &mut WorkCount,
    ) -> Result<Energies<T>, Error> {
        let free = self.mesh.free_index();
        let mut e = Energies {
            elastic: elements.energy,
            ..Energies::default()
        };
        let mut force_sum = elements.force_sum;
        self.see_nodes(x);

        // Springs, Gauss–Newton through the projection, reweighted by Huber's loss.
        let observations = self.features.active().iter().zip(self.features.targets());
        for (slot, (&active, target)) in observations.enumerate() {
            let k_spring = self.spring_weight(active);
            let (t, tet, w) = self.feature_element(slot)?;
            let ft = free_of(free, tet);
            let (p, rays) = seen_point(self.rays, self.seen, tet, w).ok_or(Error::NoFeatures)?;
            let (uv, j) = match self.camera.project_with_jacobian(&p, slot) {
                Ok(projected) => projected,
                // Not observed: nothing pulls it, wherever it is.
                Err(_) if active == 0 => continue,
                Err(_) => return Err(self.features.behind_camera(slot)),
            };
            let r = nalgebra::Vector2::new(target[0] - uv.x, target[1] - uv.y);
            let (rho, weight) = huber(r.norm_squared(), self.spring_threshold_px);
            e.spring += k_spring * rho;
            let k = k_spring * weight;
            let jr = j.transpose() * r * k;
            force_sum += jr.abs().sum();
            for ((&f, &wa), e_a) in ft.iter().zip(w).zip(&rays) {
                add_gradient(grad, f, &across(e_a, &(-jr * wa)));
            }
            if let Some(h) = hessian.as_deref_mut() {
                // The block of nodes `a`, `b` is `k w_a w_b P_a JᵀJ P_b` with `P_a = I − e_a
                // e_aᵀ` (the spring acts across the rays): `(J P_a)ᵀ (J P_b)`, each `J P_a` (2 × 3)
                // formed once per node rather than projecting every block from both sides.
                let jp = rays.map(|e| across_rays(&j, &e));
                let scatter = self.scatter.get(t).ok_or(Error::SymbolicMismatch)?;
                for (&(a, b), starts) in PAIRS.iter().zip(scatter.as_chunks::<3>().0) {
                    // `a`, `b` < 4 (the pairs of a tetrahedron's nodes).
                    if let (Some(&wa), Some(&wb), Some(&fa), Some(&fb), Some(ja), Some(jb)) = (
                        w.get(a),
                        w.get(b),
                        ft.get(a),
                        ft.get(b),
                        jp.get(a),
                        jp.get(b),
                    ) {
                        let m = ja.transpose() * jb * (k * wa * wb);
                        add_block(h, starts, a == b, fa >= fb, &m);
                    }
                }
            }
            work.feature_evaluations += 1;
        }

        // Damping toward the previous frame. `free` has the `n_nodes()` entries of the mesh,
        // and `x`, the weights, the previous and the rest positions at least as many. The pattern
        // was built for these free nodes and its invariants ([`UpperCsc::new`]) end every
        // column with its diagonal, so no entry below falls outside `col_ptr` or `h`.
        let axis = self.camera.view_direction();
        let nodes = free
            .iter()
            .zip(self.damping.iter().zip(self.depth_weight))
            .zip(x.iter().zip(self.previous).zip(self.mesh.rest()));
        for ((&f, (&c, &r)), ((p, p_previous), p_rest)) in nodes {
            if f == NONE {
                continue;
            }
            let d = vec3(p) - vec3(p_previous);
            e.damping += T::of(0.5) * c * d.norm_squared();
            add_gradient(grad, f, &(d * c));
            force_sum += (d * c).abs().sum();
            if let Some(h) = hessian.as_deref_mut() {
                // The diagonal entry is the last of its column in the upper pattern.
                for &end in column_ends(self.col_ptr, f) {
                    if let Some(hd) = h.get_mut(ux(end).wrapping_sub(1)) {
                        *hd += c;
                    }
                }
            }
            // The prior on depth: `r (d · e) e` and `r e eᵀ`, `e` the optical axis.
            let r = r * self.depth_scale;
            if r > T::zero() {
                let u = vec3(p) - vec3(p_rest);
                let s = u.dot(&axis);
                e.depth += T::of(0.5) * r * s * s;
                add_gradient(grad, f, &(axis * (r * s)));
                force_sum += (axis * (r * s)).abs().sum();
                if let Some(h) = hessian.as_deref_mut() {
                    // Column 3f + c of the diagonal block ends with its rows 3f ..= 3f + c.
                    let e_arr = [axis.x, axis.y, axis.z];
                    let ends = column_ends(self.col_ptr, f);
                    for (col, (&end, &e_col)) in ends.iter().zip(&e_arr).enumerate() {
                        let rows = ux(end).wrapping_sub(1 + col)..ux(end);
                        if let Some(dst) = h.get_mut(rows) {
                            for (hv, &e_row) in dst.iter_mut().zip(&e_arr) {
                                *hv += r * e_row * e_col;
                            }
                        }
                    }
                }
            }
        }
        let x_max = x.iter().fold(T::zero(), |m, p| {
            m.max(p[0].abs()).max(p[1].abs()).max(p[2].abs())
        });
        e.rounding = T::of(8.0) * T::EPS * x_max * force_sum;
        work.assemblies += 1;
        Ok(e)
    }
}

/// The unit camera ray through each of the first `n` nodes' positions `previous`, into `rays`
/// (as many as both hold): computed once per assembly for every node rather than four times
/// per feature in every spring evaluation, as a frame's rays depend only on where it started.
pub(crate) fn camera_rays<T: Real>(camera: &Camera<T>, previous: &[[T; 3]], rays: &mut [[T; 3]]) {
    for (ray, before) in rays.iter_mut().zip(previous) {
        let e = camera.ray_direction_through(&vec3(before));
        *ray = [e.x, e.y, e.z];
    }
}

/// The point of a virtual feature that its spring sees, `Σ_a w_a y_a` over the nodes `y_a` as
/// the springs see them ([`Problem::see_nodes`]), and the unit rays `e_a` through the
/// element's nodes at the previous frame ([`camera_rays`]).
// Inlined always: once per feature and assembly, and where the compiler took it out of line
// its two arrays of four went through memory (about 30 instructions a call more on the liver).
#[inline(always)]
fn seen_point<T: Real>(
    rays: &[[T; 3]],
    seen: &[Cell<[T; 3]>],
    tet: &[u32; 4],
    w: &[T; 4],
) -> Option<(Vector3<T>, [Vector3<T>; 4])> {
    let mut p = Vector3::zeros();
    let mut element_rays = [Vector3::zeros(); 4];
    for ((&v, &wa), ray) in tet.iter().zip(w).zip(element_rays.iter_mut()) {
        *ray = vec3(rays.get(ux(v))?);
        p += vec3(&seen.get(ux(v))?.get()) * wa;
    }
    Some((p, element_rays))
}

/// `J (I − e eᵀ)`: the projection's Jacobian `J` (2 × 3) for motion across the unit ray `e`.
/// A spring's Gauss–Newton block of nodes `a`, `b` is `(J P_a)ᵀ (J P_b)` scaled.
fn across_rays<T: Real>(j: &Matrix2x3<T>, e: &Vector3<T>) -> Matrix2x3<T> {
    j - (j * e) * e.transpose()
}

/// `g` without its component along the unit vector `e`.
fn across<T: Real>(e: &Vector3<T>, g: &Vector3<T>) -> Vector3<T> {
    g - e * e.dot(g)
}

/// Adds `g` to the three unknowns of free node `f` (nothing for a fixed node, [`NONE`]). `grad`
/// holds the `3 · n_free` unknowns of the free nodes.
fn add_gradient<T: Real>(grad: &mut [T], f: u32, g: &Vector3<T>) {
    if f != NONE {
        let base = 3 * ux(f);
        if let Some([gx, gy, gz]) = grad.get_mut(base..base + 3) {
            *gx += g.x;
            *gy += g.y;
            *gz += g.z;
        }
    }
}

/// Adds the `3 × 3` block `m` of a local node pair into the upper pattern, at `starts` (the
/// position of the block's first row in each of its three columns, [`NONE`] when a node of the
/// pair is fixed): on the diagonal (`diagonal`) only the upper triangle is stored; where the
/// global order of the two nodes is reversed (`transpose`), the stored block is the transpose.
/// The scatter map was built against this pattern ([`build_scatter`]), so every entry lies in
/// `h`.
fn add_block<T: Real>(
    h: &mut [T],
    starts: &[u32; 3],
    diagonal: bool,
    transpose: bool,
    m: &Matrix3<T>,
) {
    if starts[0] == NONE {
        return;
    }
    // Column-major: `columns[c][r]` is `m[(r, c)]`.
    let columns: &[[T; 3]; 3] = m.as_ref();
    for (c, (&s, column)) in starts.iter().zip(columns).enumerate() {
        let s = ux(s);
        if diagonal {
            // Rows `0..=c` of column `c`.
            if let Some(dst) = h.get_mut(s..=s + c) {
                for (hv, &v) in dst.iter_mut().zip(column) {
                    *hv += v;
                }
            }
        } else if let Some(dst) = h.get_mut(s..s + 3) {
            if transpose {
                // Row `c` of `m`: `m[(c, r)]` is `columns[r][c]`.
                for (hv, other) in dst.iter_mut().zip(columns) {
                    if let Some(&v) = other.get(c) {
                        *hv += v;
                    }
                }
            } else {
                for (hv, &v) in dst.iter_mut().zip(column) {
                    *hv += v;
                }
            }
        }
    }
}

/// Builds the scatter map of every tetrahedron for the pattern `a`.
///
/// # Errors
/// [`Error::SymbolicMismatch`] if a block the mesh needs is missing from the pattern.
pub(crate) fn build_scatter<T: Real>(
    mesh: &Mesh<'_, T>,
    a: &UpperCsc<'_>,
    scatter: &mut [[u32; 30]],
) -> Result<(), Error> {
    let free = mesh.free_index();
    ensure_len(scatter, mesh.n_tets(), Resource::Tetrahedra)?;
    for (tet, map) in mesh.tets().iter().zip(scatter.iter_mut()) {
        let ft = free_of(free, tet);
        for (&(la, lb), starts) in PAIRS.iter().zip(map.as_chunks_mut::<3>().0) {
            let fa = ft.get(la).copied().unwrap_or(NONE);
            let fb = ft.get(lb).copied().unwrap_or(NONE);
            for (c, start) in starts.iter_mut().enumerate() {
                *start = if fa == NONE || fb == NONE {
                    NONE
                } else {
                    let (lo, hi) = (fa.min(fb) as usize, fa.max(fb) as usize);
                    a.find(3 * lo, 3 * hi + c).ok_or(Error::SymbolicMismatch)? as u32
                };
            }
        }
    }
    Ok(())
}

// The unit tests compute in `f64`: an `f32`-only build has none.
#[cfg(all(test, feature = "f64"))]
mod tests {
    use super::{across_rays, huber};
    use nalgebra::{Matrix2x3, Matrix3, Vector3};

    /// The spring block from the rays' projections formed once per node equals `JᵀJ` projected
    /// from both sides, `(I − e_a e_aᵀ) JᵀJ (I − e_b e_bᵀ)`, to rounding.
    #[test]
    fn spring_blocks_from_projected_jacobians_match_the_two_sided_projection() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        for _ in 0..200 {
            let j = Matrix2x3::from_fn(|_, _| 500.0 * next());
            let ea = Vector3::new(next(), next(), next()).normalize();
            let eb = Vector3::new(next(), next(), next()).normalize();
            let jtj = j.transpose() * j;
            let (pa, pb) = (
                Matrix3::identity() - ea * ea.transpose(),
                Matrix3::identity() - eb * eb.transpose(),
            );
            let two_sided = pa * jtj * pb;
            let ours = across_rays(&j, &ea).transpose() * across_rays(&j, &eb);
            let err = (ours - two_sided).norm() / jtj.norm();
            assert!(err < 1e-14, "{err:e}");
            // Across the rays only: nothing along `e_a` on the left or `e_b` on the right.
            assert!((ours * eb).norm() < 1e-12 * jtj.norm());
            assert!((ea.transpose() * ours).norm() < 1e-12 * jtj.norm());
        }
    }

    /// The weight is the loss's derivative over the residual (checked against central
    /// differences of the loss), the loss is continuous at the threshold, and an infinite
    /// threshold gives the quadratic spring exactly.
    #[test]
    fn huber_weight_is_the_derivative_of_its_loss() {
        let delta = 3.0;
        let rho = |r: f64| huber(r * r, delta).0;
        for r in [0.1, 1.0, 2.9, 3.1, 5.0, 40.0, 1e4] {
            let h = 1e-6 * r;
            let derivative = (rho(r + h) - rho(r - h)) / (2.0 * h);
            let (_, w) = huber(r * r, delta);
            assert!(
                (w * r - derivative).abs() <= 1e-6 * derivative.abs(),
                "r = {r}: w r = {}, ρ' = {derivative}",
                w * r
            );
        }
        let (below, above) = (rho(delta * (1.0 - 1e-12)), rho(delta * (1.0 + 1e-12)));
        assert!((below - above).abs() < 1e-9);
        for r2 in [0.0, 0.5, 7.0, 1e12] {
            assert_eq!(huber(r2, f64::INFINITY), (0.5 * r2, 1.0));
        }
    }
}
