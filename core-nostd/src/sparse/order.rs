//! A fill-reducing ordering: minimum degree on the quotient graph, in a fixed workspace.
//!
//! Eliminating a vertex `p` of a sparse symmetric matrix joins all its neighbours into a clique;
//! minimum degree eliminates, at each step, a vertex with the fewest neighbours. Storing those
//! cliques explicitly would need unbounded memory, so, as in AMD (Amestoy, Davis and Duff), each
//! eliminated vertex becomes an *element*: a list of the variables of its clique. A variable's
//! list holds the elements it belongs to, then the variables it is still joined to directly.
//! When `p` is eliminated, the elements `p` belongs to are absorbed into the new element `p`, so
//! the total length of all lists never grows and everything fits in the original adjacency plus
//! `n` entries of room for the list being built (compacted when the room runs out).
//!
//! Unlike AMD, degrees are exact (recounted with a marker array for every variable the
//! elimination touches). As in AMD and Liu's multiple minimum degree, variables that become
//! indistinguishable (the same elements and the same neighbours, found by a hash of their lists
//! and then compared) are merged into one *supervariable*, weighted by its size, eliminated at
//! once, and the degree that decides is the *external* degree: the weight of the other
//! variables a variable is joined to, not counting its own supervariable. Counting a
//! supervariable's own members, as plain minimum degree does, delays the elimination of exactly
//! the groups whose elimination is cheapest, and costs 5–15 % more fill on tetrahedral meshes of
//! 1000 nodes and more. The stiffness matrix is ordered on its graph of nodes, whose three
//! unknowns are the natural supervariables, and the result is expanded with
//! [`expand_block_permutation`].

use super::dissect::{nested_dissection, nested_dissection_work_len};
use super::pattern::Graph;
use super::{NONE, ux};
use crate::error::{Error, Resource};
use crate::storage::{Slab, ensure_exact_len, sum, times};

/// Length of the `u32` workspace [`minimum_degree`] needs for a graph of `n` vertices and `nnz`
/// adjacency entries.
pub const fn minimum_degree_work_len(n: usize, nnz: usize) -> usize {
    sum(&[nnz, times(15, n), 1])
}

const VARIABLE: u32 = 0;
const ELEMENT: u32 = 1;
const ABSORBED: u32 = 2;
/// A variable merged into a supervariable (which stands for it from then on).
const MERGED: u32 = 3;

/// The quotient graph and the degree buckets, all carved from one workspace.
struct Quotient<'w> {
    /// List storage: lists of live objects lie in `iw[..pfree]`.
    iw: &'w mut [u32],
    pfree: usize,
    /// Start and length of each object's list.
    pe: &'w mut [u32],
    len: &'w mut [u32],
    /// Variables: how many entries at the front of the list are elements.
    elen: &'w mut [u32],
    state: &'w mut [u32],
    degree: &'w mut [u32],
    /// Doubly linked bucket lists of variables by degree.
    head: &'w mut [u32],
    next: &'w mut [u32],
    prev: &'w mut [u32],
    mark: &'w mut [u32],
    stamp: u32,
    /// Scratch for the compaction.
    order: &'w mut [u32],
    /// Supervariables: how many original vertices each stands for (0 once merged), the chain
    /// of its members (`member_next`, from the supervariable itself, ending in `NONE`) and the
    /// chain's last member.
    weight: &'w mut [u32],
    member_next: &'w mut [u32],
    member_last: &'w mut [u32],
    /// Hash of each variable's list, to find indistinguishable variables.
    hash: &'w mut [u32],
}

/// Computes a fill-reducing ordering of the graph's vertices: `perm[k]` is the vertex
/// eliminated `k`-th. `perm` needs exactly `graph.n()` entries and `work`
/// [`minimum_degree_work_len`]`(n, graph.nnz())`; the work has no meaning on return.
///
/// Cost: about the sum over eliminated vertices of the squared size of their clique, which is
/// the work of the factorization itself; it runs once per mesh topology, not per frame.
///
/// # Errors
/// [`Error::Length`] if `perm` has the wrong length, [`Error::Capacity`] if `work` is too short.
/// The same [`Error::Capacity`] of the workspace, with `needed` and `available` 0, reports
/// bookkeeping that contradicts itself (an index out of range, a list that does not fit),
/// which correct code never produces.
// Kept out of line so that a firmware build's symbols show whether it is linked
// (tests/firmware.rs).
#[inline(never)]
pub fn minimum_degree(graph: &Graph<'_>, perm: &mut [u32], work: &mut [u32]) -> Result<(), Error> {
    let n = graph.n();
    ensure_exact_len(perm, n, Resource::Permutation)?;
    let mut slab = Slab::new(work, Resource::Workspace);
    let mut q = Quotient {
        iw: slab.take(graph.nnz() + n)?,
        pfree: graph.nnz(),
        pe: slab.take(n)?,
        len: slab.take(n)?,
        elen: slab.take(n)?,
        state: slab.take(n)?,
        degree: slab.take(n)?,
        head: slab.take(n + 1)?,
        next: slab.take(n)?,
        prev: slab.take(n)?,
        mark: slab.take(n)?,
        stamp: 0,
        order: slab.take(n)?,
        weight: slab.take(n)?,
        member_next: slab.take(n)?,
        member_last: slab.take(n)?,
        hash: slab.take(n)?,
    };
    // `iw` was taken with `nnz + n` entries: the adjacency fits at its front.
    let Some(adjacency) = q.iw.get_mut(..graph.nnz()) else {
        return Err(internal());
    };
    adjacency.copy_from_slice(graph.adj());
    q.head.fill(NONE);
    q.mark.fill(0);
    q.elen.fill(0);
    q.state.fill(VARIABLE);
    q.weight.fill(1);
    q.member_next.fill(NONE);
    // The graph's `n + 1` pointers give the `n` lists, in place in the copied adjacency.
    let ptr = graph.ptr();
    let bounds = ptr.iter().zip(ptr.iter().skip(1));
    let (pe, len, degree) = (q.pe.iter_mut(), q.len.iter_mut(), q.degree.iter_mut());
    for ((&s, &e), (pe, (len, degree))) in bounds.zip(pe.zip(len.zip(degree))) {
        *pe = s;
        *len = e - s;
        *degree = e - s;
    }
    for (v, last) in q.member_last.iter_mut().enumerate() {
        *last = v as u32;
    }
    for v in 0..n {
        q.bucket_insert(v)?;
    }
    let mut min_degree = 0usize;
    let mut eliminated = 0usize;
    while eliminated < n {
        while min_degree < n && q.head.get(min_degree) == Some(&NONE) {
            min_degree += 1;
        }
        let p = match q.head.get(min_degree) {
            Some(&p) if p != NONE => ux(p),
            _ => return Err(internal()),
        };
        q.bucket_remove(p)?;
        // The supervariable's members are eliminated together, in the order they joined.
        let mut v = p as u32;
        while v != NONE {
            *perm.get_mut(eliminated).ok_or_else(internal)? = v;
            eliminated += 1;
            v = at(q.member_next, ux(v))?;
        }
        q.eliminate(p)?;
        // Degrees of the variables in the new element were recounted and may have dropped.
        for &i in list(q.iw, q.pe, q.len, p)? {
            if at(q.state, ux(i))? == VARIABLE {
                min_degree = min_degree.min(ux(at(q.degree, ux(i))?));
            }
        }
    }
    Ok(())
}

/// The workspace bookkeeping contradicted itself; with correct code this cannot happen, and it
/// is reported rather than panicking.
#[cold]
pub(super) fn internal() -> Error {
    Error::Capacity {
        resource: Resource::Workspace,
        needed: 0,
        available: 0,
    }
}

/// `x[i]`, or [`Error::IndexOutOfRange`] naming the workspace, `i` and the array's length
/// (a contradiction of the bookkeeping, like [`internal`]).
pub(super) fn at(x: &[u32], i: usize) -> Result<u32, Error> {
    x.get(i).copied().ok_or_else(|| outside(i, i, x.len()))
}

/// `&mut x[i]`, or the error of [`at`].
pub(super) fn at_mut(x: &mut [u32], i: usize) -> Result<&mut u32, Error> {
    let bound = x.len();
    x.get_mut(i).ok_or_else(|| outside(i, i, bound))
}

/// [`Error::IndexOutOfRange`] naming [`Resource::Workspace`]: `index` at `position` of a
/// workspace array of `bound` entries.
#[cold]
fn outside(position: usize, index: usize, bound: usize) -> Error {
    Error::IndexOutOfRange {
        resource: Resource::Workspace,
        position,
        index,
        bound,
    }
}

/// The list of object `v`, `iw[pe[v]..pe[v] + len[v]]`, or the error of [`at`] (naming `v`
/// and the list's end) if it is not inside `iw`. An empty list is empty whatever its start, which compaction leaves stale.
fn list<'a>(iw: &'a [u32], pe: &[u32], len: &[u32], v: usize) -> Result<&'a [u32], Error> {
    let l = ux(at(len, v)?);
    if l == 0 {
        return Ok(&[]);
    }
    let s = ux(at(pe, v)?);
    iw.get(s..s + l).ok_or_else(|| outside(v, s + l, iw.len()))
}

/// [`list`], mutable.
fn list_mut<'a>(
    iw: &'a mut [u32],
    pe: &[u32],
    len: &[u32],
    v: usize,
) -> Result<&'a mut [u32], Error> {
    let l = ux(at(len, v)?);
    if l == 0 {
        return Ok(&mut []);
    }
    let s = ux(at(pe, v)?);
    let bound = iw.len();
    iw.get_mut(s..s + l).ok_or_else(|| outside(v, s + l, bound))
}

impl Quotient<'_> {
    fn bucket_insert(&mut self, v: usize) -> Result<(), Error> {
        let d = ux(at(self.degree, v)?).min(self.head.len().saturating_sub(1));
        let h = at(self.head, d)?;
        *at_mut(self.next, v)? = h;
        *at_mut(self.prev, v)? = NONE;
        if h != NONE {
            *at_mut(self.prev, ux(h))? = v as u32;
        }
        *at_mut(self.head, d)? = v as u32;
        Ok(())
    }

    fn bucket_remove(&mut self, v: usize) -> Result<(), Error> {
        let d = ux(at(self.degree, v)?).min(self.head.len().saturating_sub(1));
        let (nx, pv) = (at(self.next, v)?, at(self.prev, v)?);
        if pv != NONE {
            *at_mut(self.next, ux(pv))? = nx;
        } else {
            *at_mut(self.head, d)? = nx;
        }
        if nx != NONE {
            *at_mut(self.prev, ux(nx))? = pv;
        }
        Ok(())
    }

    fn new_stamp(&mut self) -> u32 {
        if self.stamp == u32::MAX {
            self.mark.fill(0);
            self.stamp = 0;
        }
        self.stamp += 1;
        self.stamp
    }

    /// Eliminates variable `p`: builds element `p`, absorbs the elements `p` belonged to,
    /// prunes the lists of the variables in the new element and recounts their degrees.
    fn eliminate(&mut self, p: usize) -> Result<(), Error> {
        // The degree of `p` is exact, so the new element has exactly that many variables.
        let size = ux(at(self.degree, p)?);
        if self.pfree + size > self.iw.len() {
            self.compact()?;
            if self.pfree + size > self.iw.len() {
                return Err(internal());
            }
        }
        let s = self.new_stamp();
        *at_mut(self.mark, p)? = s;
        let start = self.pfree;
        // Every live list lies in `iw[..pfree]`; element `p` is built in the room after it.
        let Some((lists, room)) = self.iw.split_at_mut_checked(start) else {
            return Err(internal());
        };
        let lists: &[u32] = lists;
        let mut room = room.iter_mut();
        let p_list = list(lists, self.pe, self.len, p)?;
        let Some((elements, variables)) = p_list.split_at_checked(ux(at(self.elen, p)?)) else {
            return Err(internal());
        };
        for &x in elements {
            // An element `p` belongs to: its variables join element `p`, and it is absorbed.
            let x = ux(x);
            for &v in list(lists, self.pe, self.len, x)? {
                let v = ux(v);
                if at(self.state, v)? == VARIABLE {
                    let mark = at_mut(self.mark, v)?;
                    if *mark != s {
                        *mark = s;
                        *room.next().ok_or_else(internal)? = v as u32;
                        self.pfree += 1;
                    }
                }
            }
            *at_mut(self.state, x)? = ABSORBED;
            *at_mut(self.len, x)? = 0;
        }
        for &x in variables {
            let x = ux(x);
            if at(self.state, x)? == VARIABLE {
                let mark = at_mut(self.mark, x)?;
                if *mark != s {
                    *mark = s;
                    *room.next().ok_or_else(internal)? = x as u32;
                    self.pfree += 1;
                }
            }
        }
        *at_mut(self.state, p)? = ELEMENT;
        *at_mut(self.pe, p)? = start as u32;
        *at_mut(self.len, p)? = (self.pfree - start) as u32;
        *at_mut(self.elen, p)? = 0;

        // Prune: every variable `i` in element `p` drops the absorbed elements and the variables
        // now reached through `p` (those marked `s`), and gains `p`. It loses at least one entry
        // (`p` itself or an absorbed element), so the list never grows. The variables' lists lie
        // before element `p`, in `iw[..start]`.
        let Some((lists, rest)) = self.iw.split_at_mut_checked(start) else {
            return Err(internal());
        };
        let Some(element) = rest.get(..self.pfree - start) else {
            return Err(internal());
        };
        for &i in element {
            let i = ux(i);
            let li = list_mut(lists, self.pe, self.len, i)?;
            let ie = ux(at(self.elen, i)?);
            // Kept entries are written back from the front: the write position `w` never
            // passes the read position `r`.
            let mut w = 0;
            for r in 0..ie {
                let e = at(li, r)?;
                if at(self.state, ux(e))? == ELEMENT && ux(e) != p {
                    *at_mut(li, w)? = e;
                    w += 1;
                }
            }
            let kept_elements = w;
            for r in ie..li.len() {
                let v = at(li, r)?;
                if at(self.state, ux(v))? == VARIABLE && at(self.mark, ux(v))? != s {
                    *at_mut(li, w)? = v;
                    w += 1;
                }
            }
            // Element `p` goes after the kept elements: shift the variables up by one, into the
            // first dropped entry (`None` if nothing was dropped).
            let Some(shifted) = li.get_mut(kept_elements..=w) else {
                return Err(internal());
            };
            shifted.rotate_right(1);
            if let Some(first) = shifted.first_mut() {
                *first = p as u32;
            }
            *at_mut(self.len, i)? = (w + 1) as u32;
            *at_mut(self.elen, i)? = (kept_elements + 1) as u32;
        }

        self.merge_indistinguishable(start)?;

        // Recount the exact external degree of each variable in element `p`: the weight of the
        // variables it is joined to, its own supervariable left out.
        for k in start..self.pfree {
            let i = ux(at(self.iw, k)?);
            if at(self.state, i)? != VARIABLE {
                continue;
            }
            self.bucket_remove(i)?;
            let t = self.new_stamp();
            *at_mut(self.mark, i)? = t;
            let li = list(self.iw, self.pe, self.len, i)?;
            let Some((elements, variables)) = li.split_at_checked(ux(at(self.elen, i)?)) else {
                return Err(internal());
            };
            let mut d = 0u32;
            for &x in elements {
                for &v in list(self.iw, self.pe, self.len, ux(x))? {
                    let v = ux(v);
                    if at(self.state, v)? == VARIABLE {
                        let mark = at_mut(self.mark, v)?;
                        if *mark != t {
                            *mark = t;
                            d += at(self.weight, v)?;
                        }
                    }
                }
            }
            for &x in variables {
                let x = ux(x);
                if at(self.state, x)? == VARIABLE {
                    let mark = at_mut(self.mark, x)?;
                    if *mark != t {
                        *mark = t;
                        d += at(self.weight, x)?;
                    }
                }
            }
            *at_mut(self.degree, i)? = d;
            self.bucket_insert(i)?;
        }
        Ok(())
    }

    /// Merges the variables of the element just built (`iw[start..pfree]`, pruned) that are
    /// indistinguishable: the same elements and the same neighbouring variables. Candidates
    /// share a hash of their lists; each pair is then compared entry by entry with a marker.
    fn merge_indistinguishable(&mut self, start: usize) -> Result<(), Error> {
        let Some(element) = self.iw.get(start..self.pfree) else {
            return Err(internal());
        };
        for &i in element {
            let i = ux(i);
            let h = list(self.iw, self.pe, self.len, i)?
                .iter()
                .fold(0u32, |h, &x| h.wrapping_add(x));
            *at_mut(self.hash, i)? = h;
        }
        let hash = &*self.hash;
        let Some(element) = self.iw.get_mut(start..self.pfree) else {
            return Err(internal());
        };
        // Every variable of the element has just been hashed: the fallback is never used.
        element.sort_unstable_by_key(|&v| (hash.get(ux(v)).copied().unwrap_or(NONE), v));
        let mut a = start;
        while a < self.pfree {
            let h = at(self.hash, ux(at(self.iw, a)?))?;
            let mut b = a + 1;
            while b < self.pfree && at(self.hash, ux(at(self.iw, b)?))? == h {
                b += 1;
            }
            for x in a..b {
                let i = ux(at(self.iw, x)?);
                if at(self.state, i)? != VARIABLE {
                    continue;
                }
                let t = self.new_stamp();
                let li = list(self.iw, self.pe, self.len, i)?;
                let (il, ie) = (li.len(), ux(at(self.elen, i)?));
                for &r in li {
                    *at_mut(self.mark, ux(r))? = t;
                }
                for y in x + 1..b {
                    let j = ux(at(self.iw, y)?);
                    let (jl, je) = (ux(at(self.len, j)?), ux(at(self.elen, j)?));
                    if at(self.state, j)? != VARIABLE || jl != il || je != ie {
                        continue;
                    }
                    let lj = list(self.iw, self.pe, self.len, j)?;
                    if lj.iter().all(|&r| self.mark.get(ux(r)) == Some(&t)) {
                        self.merge(i, j)?;
                    }
                }
            }
            a = b;
        }
        Ok(())
    }

    /// Merges variable `j` into supervariable `i`.
    fn merge(&mut self, i: usize, j: usize) -> Result<(), Error> {
        self.bucket_remove(j)?;
        let wj = at(self.weight, j)?;
        *at_mut(self.weight, i)? += wj;
        *at_mut(self.weight, j)? = 0;
        *at_mut(self.state, j)? = MERGED;
        *at_mut(self.len, j)? = 0;
        *at_mut(self.elen, j)? = 0;
        let last = ux(at(self.member_last, i)?);
        *at_mut(self.member_next, last)? = j as u32;
        *at_mut(self.member_last, i)? = at(self.member_last, j)?;
        Ok(())
    }

    /// Moves the lists of all live objects to the front of `iw`, in their current order.
    fn compact(&mut self) -> Result<(), Error> {
        let mut live = 0;
        let mut out = self.order.iter_mut();
        for (v, (&state, &len)) in self.state.iter().zip(self.len.iter()).enumerate() {
            if state != ABSORBED && len > 0 {
                *out.next().ok_or_else(internal)? = v as u32;
                live += 1;
            }
        }
        let pe = &*self.pe;
        let Some(order) = self.order.get_mut(..live) else {
            return Err(internal());
        };
        // Every live object is a vertex below `n`: the fallback is never used.
        order.sort_unstable_by_key(|&v| pe.get(ux(v)).copied().unwrap_or(NONE));
        let mut to = 0usize;
        for &v in order.iter() {
            let v = ux(v);
            let (s, l) = (ux(at(self.pe, v)?), ux(at(self.len, v)?));
            // The live lists are disjoint and taken by start, so each moves down (`to <= s`)
            // and stays inside `iw`.
            if to > s || self.iw.get(s..s + l).is_none() {
                return Err(internal());
            }
            self.iw.copy_within(s..s + l, to);
            *at_mut(self.pe, v)? = to as u32;
            to += l;
        }
        self.pfree = to;
        Ok(())
    }
}

/// Length of the `u32` workspace [`fill_reducing_order`] needs for a graph of `n` vertices and
/// `nnz` adjacency entries.
pub const fn fill_reducing_order_work_len(n: usize, nnz: usize) -> usize {
    sum(&[nested_dissection_work_len(n, nnz), n])
}

/// Graphs of at most this many vertices are ordered by [`minimum_degree`] alone. On every mesh
/// measured below it (box meshes of 250 to 1000 nodes, as generated and shuffled, the coarse
/// liver and the committed scenes, cut or not) minimum degree filled less than nested
/// dissection, whose separators are then a large share of the graph; trying both there would
/// only add to every cut event's rebuild (about 5 % of its instructions).
pub const DISSECTION_FROM: usize = 1000;

/// The ordering the model factors under: [`minimum_degree`], and, on graphs of more than
/// [`DISSECTION_FROM`] vertices, also [`nested_dissection`], keeping the one whose factor has
/// fewer entries ([`elimination_fill`], minimum degree on a tie). Neither wins everywhere:
/// minimum degree is the better on small or irregular meshes (the coarse and the fine liver),
/// nested dissection on larger regular ones, where minimum degree's local choices cost it
/// 5–10 % more fill than AMD. `perm` needs exactly `graph.n()` entries and `work`
/// [`fill_reducing_order_work_len`]`(n, graph.nnz())`.
///
/// # Errors
/// As [`minimum_degree`].
pub fn fill_reducing_order(
    graph: &Graph<'_>,
    perm: &mut [u32],
    work: &mut [u32],
) -> Result<(), Error> {
    let n = graph.n();
    ensure_exact_len(perm, n, Resource::Permutation)?;
    let mut slab = Slab::new(work, Resource::Workspace);
    let other = slab.take(n)?;
    let scratch = slab.take(nested_dissection_work_len(n, graph.nnz()))?;
    minimum_degree(graph, perm, scratch)?;
    if n > DISSECTION_FROM {
        nested_dissection(graph, other, scratch)?;
        if elimination_fill(graph, other, scratch)? < elimination_fill(graph, perm, scratch)? {
            perm.copy_from_slice(other);
        }
    }
    postorder(graph, perm, scratch)
}

/// Length of the `u32` workspace [`postorder`] needs for `n` vertices.
pub const fn postorder_work_len(n: usize) -> usize {
    times(5, n)
}

/// Renumbers the ordering `perm` in a postorder of its elimination tree: each subtree's
/// vertices consecutive, a parent right after its children, the children in the order `perm`
/// had them. The factor has the same pattern up to that renumbering (the same fill, the same
/// tree), and the last child of every vertex comes just before it, so chains of the tree
/// are runs of consecutive columns: what the relaxed supernodes of the symbolic analysis
/// merge. `work` needs [`postorder_work_len`]`(n)` entries.
///
/// # Errors
/// As [`elimination_fill`].
pub fn postorder(graph: &Graph<'_>, perm: &mut [u32], work: &mut [u32]) -> Result<(), Error> {
    let n = graph.n();
    ensure_exact_len(perm, n, Resource::Permutation)?;
    let mut slab = Slab::new(work, Resource::Workspace);
    let (position, parent, mark) = (slab.take(n)?, slab.take(n)?, slab.take(n)?);
    let (stack, post) = (slab.take(n)?, slab.take(n)?);
    elimination_tree_of(graph, perm, position, parent, mark)?;
    // Children lists (`head`, `next`: in `position`'s and `mark`'s room), each in increasing
    // order, then a depth-first walk from every root in increasing order.
    let (head, next) = (position, mark);
    head.fill(NONE);
    for j in (0..n).rev() {
        let p = at(parent, j)?;
        if p != NONE {
            *at_mut(next, j)? = at(head, ux(p))?;
            *at_mut(head, ux(p))? = j as u32;
        }
    }
    let mut k = 0;
    for root in 0..n {
        if at(parent, root)? != NONE {
            continue;
        }
        let mut top = 0;
        *at_mut(stack, top)? = root as u32;
        loop {
            let v = ux(at(stack, top)?);
            let child = at(head, v)?;
            if child == NONE {
                *at_mut(post, k)? = at(perm, v)?;
                k += 1;
                if top == 0 {
                    break;
                }
                top -= 1;
            } else {
                *at_mut(head, v)? = at(next, ux(child))?;
                top += 1;
                *at_mut(stack, top)? = child;
            }
        }
    }
    perm.copy_from_slice(post);
    Ok(())
}

/// Length of the `u32` workspace [`elimination_fill`] needs for `n` vertices.
pub const fn elimination_fill_work_len(n: usize) -> usize {
    times(3, n)
}

/// The entries of the strictly lower Cholesky factor of a matrix with the graph's pattern,
/// eliminated in the order `perm` (`perm[k]` the `k`-th vertex): row by row, each row's entries
/// are the elimination-tree paths from its earlier neighbours up to it (the row subtree), with
/// the tree built as the rows are. Cost: proportional to the count. `work` needs
/// [`elimination_fill_work_len`]`(n)` entries.
///
/// # Errors
/// [`Error::Length`] if `perm` has not `graph.n()` entries, [`Error::Capacity`] if `work` is
/// too short, [`Error::NotAPermutation`] (naming the position) if `perm` repeats a vertex, and
/// [`Error::IndexOutOfRange`] if it names one beyond the graph.
pub fn elimination_fill(graph: &Graph<'_>, perm: &[u32], work: &mut [u32]) -> Result<u64, Error> {
    let n = graph.n();
    ensure_exact_len(perm, n, Resource::Permutation)?;
    let mut slab = Slab::new(work, Resource::Workspace);
    let (position, parent, mark) = (slab.take(n)?, slab.take(n)?, slab.take(n)?);
    elimination_tree_of(graph, perm, position, parent, mark)
}

/// The elimination tree of `graph` eliminated in the order `perm` into `parent` (by position
/// in the order, [`NONE`] for a root), built row by row as the rows' subtrees are walked;
/// returns the strictly lower factor's entries, the walks' length. `position` ends with each
/// vertex's place in the order, `mark` with no meaning; all three hold `graph.n()` entries.
///
/// # Errors
/// As [`elimination_fill`].
fn elimination_tree_of(
    graph: &Graph<'_>,
    perm: &[u32],
    position: &mut [u32],
    parent: &mut [u32],
    mark: &mut [u32],
) -> Result<u64, Error> {
    let n = graph.n();
    ensure_exact_len(perm, n, Resource::Permutation)?;
    position.fill(NONE);
    for (k, &v) in perm.iter().enumerate() {
        let p = position.get_mut(ux(v)).ok_or(Error::IndexOutOfRange {
            resource: Resource::Permutation,
            position: k,
            index: ux(v),
            bound: n,
        })?;
        if *p != NONE {
            return Err(Error::NotAPermutation { position: k });
        }
        *p = k as u32;
    }
    let mut count = 0u64;
    for (k, &v) in perm.iter().enumerate() {
        *at_mut(parent, k)? = NONE;
        *at_mut(mark, k)? = k as u32;
        for &w in graph.neighbours(ux(v)) {
            let mut j = ux(at(position, ux(w))?);
            if j >= k {
                continue;
            }
            // Up the tree from `j` until a column this row already reached.
            while at(mark, j)? != k as u32 {
                count += 1;
                *at_mut(mark, j)? = k as u32;
                let p = at_mut(parent, j)?;
                if *p == NONE {
                    *p = k as u32;
                }
                j = ux(*p);
            }
        }
    }
    Ok(count)
}

/// Expands an ordering of `n` vertices into one of `b·n` unknowns, vertex `v` owning unknowns
/// `b·v .. b·v + b` (kept together, in order). `dof_perm` needs exactly `b · node_perm.len()`
/// entries.
///
/// # Errors
/// [`Error::Length`] if `dof_perm` has the wrong length.
pub fn expand_block_permutation(
    node_perm: &[u32],
    b: usize,
    dof_perm: &mut [u32],
) -> Result<(), Error> {
    ensure_exact_len(dof_perm, times(b, node_perm.len()), Resource::Permutation)?;
    if b == 0 {
        // Nothing to write (and no chunks of size 0).
        return Ok(());
    }
    for (&v, block) in node_perm.iter().zip(dof_perm.chunks_exact_mut(b)) {
        for (c, dof) in block.iter_mut().enumerate() {
            *dof = (ux(v) * b + c) as u32;
        }
    }
    Ok(())
}

// The unit tests compute in `f64`: an `f32`-only build has none.
#[cfg(all(test, feature = "f64"))]
mod tests {
    use super::*;

    fn order(n: usize, ptr: &[u32], adj: &[u32]) -> [u32; 16] {
        let g = Graph::new(n, ptr, adj).unwrap();
        let mut perm = [0u32; 16];
        let mut work = [0u32; 512];
        minimum_degree(&g, &mut perm[..n], &mut work).unwrap();
        perm
    }

    #[test]
    fn star_eliminates_leaves_before_the_centre() {
        // Vertex 0 joined to 1..5: eliminating the centre first would make a 5-clique.
        let ptr = [0u32, 5, 6, 7, 8, 9, 10];
        let adj = [1u32, 2, 3, 4, 5, 0, 0, 0, 0, 0];
        let perm = order(6, &ptr, &adj);
        assert_ne!(perm[0], 0);
        let mut seen = [false; 6];
        for &v in &perm[..6] {
            seen[v as usize] = true;
        }
        assert!(seen.iter().all(|&s| s));
    }

    #[test]
    fn path_gives_no_fill() {
        // A path 0-1-2-3-4: minimum degree eliminates from the ends, and every clique has at
        // most two vertices.
        let ptr = [0u32, 1, 3, 5, 7, 8];
        let adj = [1u32, 0, 2, 1, 3, 2, 4, 3];
        let perm = order(5, &ptr, &adj);
        assert!(perm[0] == 0 || perm[0] == 4);
    }

    #[test]
    fn empty_and_isolated() {
        let g = Graph::new(0, &[0], &[]).unwrap();
        let mut work = [0u32; 4];
        assert!(minimum_degree(&g, &mut [], &mut work).is_ok());
        let perm = order(3, &[0, 0, 0, 0], &[]);
        assert_eq!(&perm[..3], &[2, 1, 0]);
    }

    #[test]
    fn short_workspace_is_an_error() {
        let g = Graph::new(2, &[0, 1, 2], &[1, 0]).unwrap();
        let mut work = [0u32; 5];
        assert!(matches!(
            minimum_degree(&g, &mut [0, 0], &mut work),
            Err(Error::Capacity {
                resource: Resource::Workspace,
                ..
            })
        ));
    }
}
