//! The Bevy plugin without a GPU, in one test binary (Bevy links once): `models` (region
//! children, the budget split, despawn, run-time changes) and `skinned` (skinned characters
//! against reference linear blend skinning) and `view_dependent` (models refined per frame)
//! and `baked` (`.mrm` files through the asset server). One test, the drawn `soak`, uses a
//! Vulkan driver (lavapipe on machines without a GPU), as the render tests do.
#![cfg(feature = "bevy")]

mod attributes;
mod baked;
#[path = "../render/example_run.rs"]
mod example_run;
mod geomorph;
mod models;
mod prop_field;
mod shared;
mod skinned;
mod soak;
mod view_dependent;
