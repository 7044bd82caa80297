//! A model's storage: owned buffers of the sizes the core asks for, and the checks a scene's
//! capacities pass (bounds and memory budget, [`crate::limits`]) before anything is allocated.

use std::fmt;

use incise_core::mesh::MeshCapacity;
use incise_core::sparse::PrecomputedAnalysis;
use incise_core::{
    Capacities, Error as CoreError, MeshAnalysis, MeshInput, Model, ModelBuffers, ModelConfig,
    ModelSize, Real, analyse_mesh, analyse_mesh_work_len,
};
use serde::{Deserialize, Serialize};

use crate::limits::{self, Refusal};

/// What a scene asks of its model's fixed storage beyond the mesh: room for features, targets,
/// detection pairs and the cut line, and for what a cut adds. The mesh's own nodes and
/// tetrahedra are counted from the mesh; a cut's new ones come from the room reserved here.
/// A scene file and a scenario file read it as their `[capacities]` section.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct SceneCapacities {
    /// Tracked features.
    pub features: usize,
    /// Internal targets the model carries.
    pub targets: usize,
    /// Nodes a cut may add to the model's (new nodes on cut edges and node copies).
    pub cut_nodes: usize,
    /// Tetrahedra a cut may add (the pieces of split tetrahedra).
    pub cut_tets: usize,
    /// Entries of the factor `L` after every cut; absent: three times what the uncut model
    /// needs.
    pub factor_entries: Option<usize>,
    /// Neighbour pairs of the cut detection.
    pub pairs: usize,
    /// Vertices of the cut line.
    pub cut_vertices: usize,
}

impl Default for SceneCapacities {
    fn default() -> Self {
        SceneCapacities {
            features: 1024,
            targets: 64,
            cut_nodes: 256,
            cut_tets: 1024,
            factor_entries: None,
            pairs: 32_768,
            cut_vertices: 64,
        }
    }
}

impl SceneCapacities {
    /// Checks every capacity against its bound in [`crate::limits`]; with `detection` on, the
    /// detection needs room for at least one pair and a cut line of two vertices (with none,
    /// it could never report a cut).
    ///
    /// # Errors
    /// A [`Refusal`] naming the first key out of bounds.
    pub fn check(&self, detection: bool) -> Result<(), Refusal> {
        const S: &str = "capacities";
        limits::within(S, "features", self.features as u64, 1, limits::MAX_FEATURES)?;
        limits::within(S, "targets", self.targets as u64, 0, limits::MAX_TARGETS)?;
        limits::within(
            S,
            "cut_nodes",
            self.cut_nodes as u64,
            0,
            limits::MAX_CUT_NODES,
        )?;
        limits::within(S, "cut_tets", self.cut_tets as u64, 0, limits::MAX_CUT_TETS)?;
        if let Some(entries) = self.factor_entries {
            limits::within(
                S,
                "factor_entries",
                entries as u64,
                1,
                limits::MAX_FACTOR_ENTRIES,
            )?;
        }
        for (key, value, least, max, what) in [
            (
                "pairs",
                self.pairs,
                1,
                limits::MAX_PAIRS,
                "neighbour pairs to compare",
            ),
            (
                "cut_vertices",
                self.cut_vertices,
                limits::MIN_CUT_VERTICES,
                limits::MAX_CUT_VERTICES,
                "a cut line of at least two vertices",
            ),
        ] {
            if detection && (value as u64) < least {
                return Err(Refusal::new(
                    S,
                    key,
                    format!(
                        "{value}, but cut detection is on ([detection] enabled) and needs \
                         {what}; set [detection] enabled = false to run without it"
                    ),
                ));
            }
            limits::within(S, key, value as u64, 0, max)?;
        }
        Ok(())
    }
}

/// Why a model's storage was not allocated.
#[derive(Debug, Clone, PartialEq)]
pub enum StorageError {
    /// A capacity beyond its bound, or storage beyond the host's memory budget
    /// ([`crate::limits`]).
    Refused(Refusal),
    /// The core refused the mesh.
    Core(CoreError),
}

impl fmt::Display for StorageError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            StorageError::Refused(r) => write!(f, "{r}"),
            StorageError::Core(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for StorageError {}

/// A model's storage as owned vectors of the lengths [`ModelSize`] gives for a set of
/// capacities: what a host does with the core's caller-sized API. Checks nothing beyond what
/// the core checks (the tests that set every capacity, down to one too small, build on it);
/// [`ModelStorage`] checks a scene's capacities and memory first.
pub struct OwnedStorage<T, F = T> {
    /// The sizes.
    pub size: ModelSize,
    reals: Vec<T>,
    /// The factor's values and workspace, in its scalar type ([`ModelSize::factor_real_len`]).
    factor_reals: Vec<F>,
    indices: Vec<u32>,
}

impl<T: Real, F: Real> OwnedStorage<T, F> {
    /// Storage for `capacities`.
    ///
    /// # Errors
    /// The core's [`CoreError::TooLarge`] for capacities it cannot hold ([`ModelSize::new`]),
    /// before anything is allocated.
    pub fn new(capacities: &Capacities) -> Result<Self, CoreError> {
        let size = ModelSize::new(capacities)?;
        Ok(OwnedStorage {
            size,
            reals: vec![T::zero(); size.model_real_len()],
            factor_reals: vec![F::zero(); size.factor_real_len()],
            indices: vec![0; size.index_len()],
        })
    }

    /// Builds a model in this storage.
    ///
    /// # Errors
    /// The core's error.
    pub fn model<'a>(
        &'a mut self,
        mesh: &MeshInput<'_, T>,
        config: &ModelConfig<T>,
    ) -> Result<Model<'a, T, F>, CoreError> {
        let size = self.size;
        Model::new(mesh, config, &size, self.buffers()?)
    }

    /// Builds a model in this storage with the uncut mesh's ordering and symbolic analysis
    /// taken from `analysis` ([`Model::from_precomputed`]).
    ///
    /// # Errors
    /// The core's error.
    pub fn model_from_precomputed<'a>(
        &'a mut self,
        mesh: &MeshInput<'_, T>,
        config: &ModelConfig<T>,
        analysis: &PrecomputedAnalysis<'_>,
    ) -> Result<Model<'a, T, F>, CoreError> {
        let size = self.size;
        Model::from_precomputed(mesh, config, &size, self.buffers()?, analysis)
    }

    /// The three vectors as the core's bundle (the factor's scalars apart even when `F` is
    /// `T`, which [`ModelBuffers::new`] would carve out of one slice).
    fn buffers(&mut self) -> Result<ModelBuffers<'_, T, F>, CoreError> {
        ModelBuffers::new_mixed(
            &self.size,
            &mut self.reals,
            &mut self.factor_reals,
            &mut self.indices,
        )
    }

    /// Bytes of the storage (scalars and indices), what a firmware build would hold.
    pub fn bytes(&self) -> usize {
        self.size.bytes_mixed::<T, F>()
    }
}

/// The storage of one scene's model: its capacities checked against the host's bounds and
/// memory budget, then [`OwnedStorage`].
pub struct ModelStorage<T, F = T> {
    /// What the uncut mesh needs of the linear algebra.
    pub analysis: MeshAnalysis,
    storage: OwnedStorage<T, F>,
}

impl<T: Real> ModelStorage<T> {
    /// Sizes storage for `mesh` with the scene's capacities: the mesh's nodes and tetrahedra
    /// plus the room a cut may take, and the factor entries the section states (absent: three
    /// times the uncut model's). Checks the capacities and the memory first
    /// ([`ModelStorage::plan`]). [`ModelStorage::with_factor_in`] for mixed precision.
    ///
    /// # Errors
    /// As [`ModelStorage::plan`].
    pub fn new(mesh: &MeshInput<'_, T>, c: &SceneCapacities) -> Result<Self, StorageError> {
        Self::with_factor_in(mesh, c)
    }

    /// Storage for `mesh` with room for `features` features and the default capacities
    /// otherwise.
    ///
    /// # Errors
    /// As [`ModelStorage::new`].
    pub fn with_features(mesh: &MeshInput<'_, T>, features: usize) -> Result<Self, StorageError> {
        Self::new(
            mesh,
            &SceneCapacities {
                features,
                ..SceneCapacities::default()
            },
        )
    }
}

impl<T: Real, F: Real> ModelStorage<T, F> {
    /// As [`ModelStorage::new`], for a model in `T` that factorizes in `F` (mixed precision,
    /// `ModelStorage::<f64, f32>`): the factor's part of the storage in `F`.
    ///
    /// # Errors
    /// As [`ModelStorage::plan`].
    pub fn with_factor_in(
        mesh: &MeshInput<'_, T>,
        c: &SceneCapacities,
    ) -> Result<Self, StorageError> {
        let (size, analysis) = Self::plan(mesh, c)?;
        Ok(ModelStorage {
            analysis,
            storage: OwnedStorage::new(size.capacities()).map_err(StorageError::Core)?,
        })
    }

    /// The sizes [`ModelStorage::new`] would allocate, and the mesh's analysis, with nothing
    /// allocated but the analysis's workspace (the size of the mesh): every capacity is
    /// checked against its bound ([`SceneCapacities::check`]) and the storage against
    /// [`limits::MEMORY_BUDGET`].
    ///
    /// # Errors
    /// [`StorageError::Refused`] naming the capacity at fault, or the whole `[capacities]`
    /// section when only their sum is too much; [`StorageError::Core`] for a mesh or capacities
    /// the core refuses.
    pub fn plan(
        mesh: &MeshInput<'_, T>,
        c: &SceneCapacities,
    ) -> Result<(ModelSize, MeshAnalysis), StorageError> {
        c.check(false).map_err(StorageError::Refused)?;
        let (n, t) = (mesh.rest.len(), mesh.tets.len());
        let mut work = vec![0u32; analyse_mesh_work_len(n, t)];
        let analysis = analyse_mesh(mesh, &mut work).map_err(StorageError::Core)?;
        let tets = t.saturating_add(c.cut_tets);
        let caps = Capacities {
            mesh: MeshCapacity {
                nodes: n.saturating_add(c.cut_nodes),
                tets,
                surface_triangles: tets.saturating_mul(4),
            },
            features: c.features,
            targets: c.targets,
            factor_entries: c.factor_entries.unwrap_or(analysis.nnz_l.saturating_mul(3)),
            pairs: c.pairs,
            cut_vertices: c.cut_vertices,
        };
        let size = ModelSize::new(&caps).map_err(StorageError::Core)?;
        // Saturated at `usize::MAX`, which no budget admits.
        let bytes = size.bytes_mixed::<T, F>() as u128;
        limits::budget(
            "capacities",
            "",
            bytes,
            &format!(
                "the model's storage ({n} nodes and {t} tetrahedra, with room for {} features, \
                 {} pairs, {} cut nodes, {} cut tetrahedra and {} factor entries)",
                caps.features, caps.pairs, c.cut_nodes, c.cut_tets, caps.factor_entries
            ),
        )
        .map_err(StorageError::Refused)?;
        Ok((size, analysis))
    }

    /// Builds the model in this storage.
    ///
    /// # Errors
    /// The core's error.
    pub fn model<'a>(
        &'a mut self,
        mesh: &MeshInput<'_, T>,
        config: &ModelConfig<T>,
    ) -> Result<Model<'a, T, F>, CoreError> {
        self.storage.model(mesh, config)
    }

    /// Bytes of the model's storage (scalars and indices), what a firmware build would hold.
    pub fn bytes(&self) -> usize {
        self.storage.bytes()
    }

    /// The sizes.
    pub fn size(&self) -> &ModelSize {
        &self.storage.size
    }
}
