//! A small model for the state tests (`tests/state.rs`) and the fuzzing of the core
//! (`tests/fuzz_core.rs`): a box held at `x = 0`, seen from above, with features on its top
//! face. Its storage is the host's `OwnedStorage`, which applies no host limits, so a test can
//! set every capacity, down to one too small.

use incise_core::{
    Camera, Capacities, Coupling, DetectionConfig, Law, Material, MeshCapacity, MeshInput, Model,
    ModelConfig, Observation, SolverConfig, Strategy, analyse_mesh, analyse_mesh_work_len,
};

use crate::scene::{camera, observe};
use crate::testmesh::box_mesh;

/// Edge lengths of the box, metres.
pub const SIZE: [f64; 3] = [0.04, 0.03, 0.01];

/// The geometry of a bench: mesh, fixed nodes, camera, and the material points of the
/// features (on the top face).
#[derive(Clone, Debug)]
pub struct Bench {
    /// Rest positions.
    pub rest: Vec<[f64; 3]>,
    /// Tetrahedra.
    pub tets: Vec<[u32; 4]>,
    /// Fixed nodes (the face `x = 0`).
    pub fixed: Vec<u32>,
    /// The camera, 0.2 m above the top face.
    pub camera: Camera<f64>,
    /// Material points of the features, id = index.
    pub points: Vec<[f64; 3]>,
}

impl Bench {
    /// A box of `cells` cells with a `side × side` grid of features on its top face.
    pub fn new(cells: [usize; 3], side: usize) -> Self {
        let mesh = box_mesh(cells, SIZE);
        let fixed = (0..mesh.nodes.len() as u32)
            .filter(|&v| mesh.nodes[v as usize][0].abs() < 1e-12)
            .collect();
        let centre = [SIZE[0] / 2.0, SIZE[1] / 2.0, SIZE[2]];
        let camera = camera(
            [centre[0], centre[1], 0.2],
            centre,
            [0.0, -1.0, 0.0],
            2000.0,
            (640, 480),
        );
        let mut points = Vec::new();
        for j in 0..side {
            for i in 0..side {
                let t = |k: usize| (k as f64 + 0.5) / side as f64;
                points.push([SIZE[0] * t(i), SIZE[1] * t(j), SIZE[2]]);
            }
        }
        Bench {
            rest: mesh.nodes,
            tets: mesh.tets,
            fixed,
            camera,
            points,
        }
    }

    /// The mesh input.
    pub fn input(&self) -> MeshInput<'_, f64> {
        MeshInput {
            rest: &self.rest,
            tets: &self.tets,
            fixed: &self.fixed,
        }
    }

    /// The features at frame 0 (their material points at rest, through the camera).
    pub fn frame0(&self) -> Vec<Observation<f64>> {
        observe(&self.camera, &self.points)
    }

    /// Frame `t` of a smooth stretch: the half of the top face beyond `x = SIZE/2` moves by up
    /// to `amplitude_px` pixels along `+u` (a pull on the free end).
    pub fn frame(&self, t: usize, amplitude_px: f64) -> Vec<Observation<f64>> {
        let s = amplitude_px * (t as f64 * 0.3).sin();
        self.frame0()
            .into_iter()
            .zip(&self.points)
            .map(|(mut o, p)| {
                o.uv[0] += s * (p[0] / SIZE[0]);
                o
            })
            .collect()
    }

    /// A model configuration: a soft material, the camera, the given strategy, paper
    /// detection defaults.
    pub fn config(&self, strategy: Strategy) -> ModelConfig<f64> {
        ModelConfig {
            material: Material {
                young: 3.0e4,
                poisson: 0.4,
                inversion_barrier: true,
                law: Law::SaintVenantKirchhoff,
            },
            camera: self.camera,
            solver: SolverConfig {
                strategy,
                newton_iterations: 2,
                line_search_steps: 3,
                coupling: Coupling::Stiffness(1e-6),
                spring_threshold: f64::INFINITY,
                damping: 0.01,
                depth_prior: 0.0,
                image_margin: 50.0,
            },
            detection: DetectionConfig::paper(),
        }
    }

    /// Capacities with room for a cut, `features` features and `pairs` pairs.
    pub fn capacities(&self, features: usize, pairs: usize) -> Capacities {
        let (n, t) = (self.rest.len(), self.tets.len());
        let mut work = vec![0u32; analyse_mesh_work_len(n, t)];
        let nnz_l = analyse_mesh(&self.input(), &mut work).map_or(0, |a| a.nnz_l);
        Capacities {
            mesh: MeshCapacity {
                nodes: n + 400,
                tets: t + 1600,
                surface_triangles: 4 * (t + 1600),
            },
            features,
            targets: 16,
            factor_entries: 4 * nnz_l + 64,
            pairs,
            cut_vertices: 32,
        }
    }
}

/// What a test compares before and after a call: the fingerprint, the positions as bits, and
/// the readable per-feature state.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Snapshot {
    /// [`Model::fingerprint`].
    pub fingerprint: u64,
    /// Every coordinate of every node, as bits.
    pub positions: Vec<u64>,
    /// Targets of the features, as bits, and their observed flags.
    pub targets: Vec<u64>,
    /// Observed flags.
    pub active: Vec<u32>,
    /// Number of internal targets.
    pub n_targets: usize,
}

impl Snapshot {
    /// The state of `model`.
    pub fn of(model: &Model<'_, f64>) -> Self {
        Snapshot {
            fingerprint: model.fingerprint(),
            positions: model
                .positions()
                .iter()
                .flatten()
                .map(|c| c.to_bits())
                .collect(),
            targets: model
                .features()
                .targets()
                .iter()
                .flatten()
                .map(|c| c.to_bits())
                .collect(),
            active: model.features().active().to_vec(),
            n_targets: model.n_targets(),
        }
    }
}
