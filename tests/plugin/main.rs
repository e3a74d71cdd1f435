//! The Bevy plugin without a GPU, in one test binary (Bevy links once): `models` (region
//! children, the budget split, despawn, run-time changes) and `skinned` (skinned characters
//! against reference linear blend skinning).
#![cfg(feature = "bevy")]

mod models;
mod skinned;
