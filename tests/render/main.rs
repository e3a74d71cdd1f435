//! The render tests, in one binary: each runs an example offscreen (Vulkan; lavapipe on
//! machines without a GPU) and checks what it drew and reported. Skipped, with a message,
//! only where no Vulkan driver is installed (CI sets `ASLOD_REQUIRE_RENDER`, which makes that
//! a failure).
#![cfg(feature = "bevy")]

mod example_run;

mod aerobic_class;
mod basic;
mod budget_tuning;
mod geomorph;
mod level_changes;
mod silvretta;
mod skinned_character;
mod textured;
mod view_dependent;
