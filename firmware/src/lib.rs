//! The firmware-style program of one scene: everything the device holds is `static` (the scene
//! from the module `incise codegen` generated, the model's storage sized by `const` lengths),
//! there is no heap and no `std`, and the model is built from the precomputed analysis, so
//! without the `cut` feature neither the ordering nor the symbolic analysis is linked.
//!
//! A C `main` (tests/firmware.rs links one) calls [`incise_firmware_run`] with a callback that
//! receives the node positions after the last frame.
#![no_std]
#![no_main]

use core::cell::UnsafeCell;
use core::sync::atomic::{AtomicBool, Ordering};

use incise_core::{Error, Model, ModelBuffers, Observation, Real};

use scene::{FactorScalar, Scalar};

#[cfg(all(feature = "mixed", feature = "f32"))]
compile_error!("`mixed` computes the model in f64 and its factor in f32: leave `f32` out");

/// The scene, as generated.
#[allow(dead_code, clippy::all)]
mod scene {
    include!(env!("INCISE_FIRMWARE_SCENE"));
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo<'_>) -> ! {
    loop {}
}

/// The model's storage: `static`, of the lengths the scene's capacities give at compile time;
/// the factor's part apart, in its own scalar (`f32` with the `mixed` feature).
struct Storage {
    reals: UnsafeCell<[Scalar; scene::MODEL_REAL_LEN]>,
    factor_reals: UnsafeCell<[FactorScalar; scene::FACTOR_REAL_LEN]>,
    indices: UnsafeCell<[u32; scene::INDEX_LEN]>,
}

// SAFETY: the buffers are only reached through `take_storage`, which hands them out once.
unsafe impl Sync for Storage {}

static STORAGE: Storage = Storage {
    reals: UnsafeCell::new([0.0; scene::MODEL_REAL_LEN]),
    factor_reals: UnsafeCell::new([0.0; scene::FACTOR_REAL_LEN]),
    indices: UnsafeCell::new([0; scene::INDEX_LEN]),
};
static TAKEN: AtomicBool = AtomicBool::new(false);

/// The static buffers (the model's scalars, the factor's, the indices), the first time only.
type Buffers = (
    &'static mut [Scalar],
    &'static mut [FactorScalar],
    &'static mut [u32],
);

/// The static buffers, the first time only.
fn take_storage() -> Option<Buffers> {
    if TAKEN.swap(true, Ordering::AcqRel) {
        return None;
    }
    // SAFETY: `TAKEN` lets this run once, so these are the only references ever made.
    let (reals, factor_reals, indices) = unsafe {
        (
            &mut *STORAGE.reals.get(),
            &mut *STORAGE.factor_reals.get(),
            &mut *STORAGE.indices.get(),
        )
    };
    Some((&mut reals[..], &mut factor_reals[..], &mut indices[..]))
}

/// Where things stopped, as [`incise_firmware_run`] returns it.
const BUILD_FAILED: i32 = 1;
const EMBED_FAILED: i32 = 2;
const STORAGE_TAKEN: i32 = 3;

/// Builds the scene's model, places its features at frame 0, steps through the other frames
/// (a frame the core refuses is skipped, as the host's run does), then calls `emit` with every
/// node's position. Returns 0, or where it stopped (1 build, 2 features, 3 called twice).
#[unsafe(no_mangle)]
pub extern "C" fn incise_firmware_run(emit: extern "C" fn(u32, f64, f64, f64)) -> i32 {
    let Some((reals, factor_reals, indices)) = take_storage() else {
        return STORAGE_TAKEN;
    };
    let built = scene::config().and_then(|config| {
        let buffers = ModelBuffers::new_mixed(&scene::SIZE, reals, factor_reals, indices)?;
        Model::<Scalar, FactorScalar>::from_precomputed(
            &scene::MESH,
            &config,
            &scene::SIZE,
            buffers,
            &scene::ANALYSIS,
        )
    });
    let Ok(mut model) = built else {
        return BUILD_FAILED;
    };
    let [first, rest @ ..] = &scene::FRAMES;
    if model.embed_features(first).is_err() {
        return EMBED_FAILED;
    }
    for frame in rest {
        let mut known = [Observation {
            id: 0,
            uv: [0.0; 2],
        }; scene::MAX_OBSERVATIONS];
        let n = observed(&model, frame, &mut known);
        // A refused frame leaves the model as it was; the device goes on with the next.
        let _: Result<_, Error> = model.step(&known[..n]);
    }
    for (v, p) in (0u32..).zip(model.positions()) {
        emit(v, p[0].to_f64(), p[1].to_f64(), p[2].to_f64());
    }
    0
}

/// Copies the observations of features the model carries (those placed at frame 0) into
/// `known`; returns how many.
fn observed(
    model: &Model<'_, Scalar, FactorScalar>,
    frame: &[Observation<Scalar>],
    known: &mut [Observation<Scalar>],
) -> usize {
    let mut n = 0;
    for o in frame {
        if model.features().slot_of(o.id).is_some()
            && let Some(slot) = known.get_mut(n)
        {
            *slot = *o;
            n += 1;
        }
    }
    n
}
