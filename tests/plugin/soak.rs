//! A long session, headless: a wandering camera over models of five kinds (regions, shared
//! levels, view-dependent, loaded from a baked file, and glTF scenes under `MultiresScene`)
//! spawned and despawned, materials, asset handles and the budget changed, an asset replaced
//! in place and the baked file re-baked and hot-reloaded. The budget holds every frame,
//! nothing panics, and once everything is despawned the `Mesh` and `MultiresMesh` assets are
//! back to where they started. It runs twice: without a GPU, and drawn through Vulkan
//! (lavapipe without a GPU), where Bevy's mesh allocator must return to its baseline too.
//! `ASLOD_SOAK_FRAMES=10000 cargo test --all-features --test plugin soak -- --test-threads=1`
//! (`make soak`) runs it long; the default is short enough for CI.

use super::baked::{asset_folder, bake_cow};
use super::example_run::require_vulkan;
use super::models::{asset, spawn_camera, terrain as patch};
use super::skinned::app_with_backends;
use super::view_dependent::cow;
use bevy::camera::RenderTarget;
use bevy::prelude::*;
use bevy::render::RenderApp;
use bevy::render::mesh::allocator::MeshAllocator;
use bevy::render::render_resource::TextureFormat;
use bevy::render::settings::Backends;
use bevy::world_serialization::WorldAssetRoot;
use bevy_aslod::plugin::{
    AslodPlugin, AslodStats, MultiresMesh, MultiresModel, MultiresModelReady, MultiresScene,
    MultiresSceneConverted, PolygonBudget, SharedLevels, ViewDependent,
};
use bevy_aslod::regions::{GridPlane, Partition};

/// Resident memory in bytes (Linux; `None` elsewhere).
pub(crate) fn resident_bytes() -> Option<u64> {
    let statm = std::fs::read_to_string("/proc/self/statm").ok()?;
    let pages: u64 = statm.split_whitespace().nth(1)?.parse().ok()?;
    Some(pages * 4096)
}

/// xorshift64: the same session every run.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    fn below(&mut self, n: u64) -> u64 {
        self.next() % n.max(1)
    }

    fn unit(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// Frames to run: `ASLOD_SOAK_FRAMES`, else `default`.
fn soak_frames(default: usize) -> usize {
    std::env::var("ASLOD_SOAK_FRAMES")
        .ok()
        .and_then(|f| f.parse().ok())
        .unwrap_or(default)
}

#[test]
fn a_long_session_holds_the_budget_and_frees_what_it_spawned() {
    soak("soak", soak_frames(600), false);
}

/// The same session drawn (Vulkan; lavapipe without a GPU) into a small image: the region
/// meshes go through Bevy's mesh allocator and the plugin's index writes, and once
/// everything is despawned the allocator holds as many bytes as before the session.
#[test]
fn a_long_rendered_session_returns_the_mesh_allocator_to_its_baseline() {
    if !require_vulkan("rendered soak") {
        return;
    }
    soak("soak-rendered", soak_frames(300), true);
}

/// Bytes and slabs in the render world's mesh allocator (`None` without a renderer).
fn allocator_bytes(app: &App) -> Option<(u64, usize)> {
    let render = app.get_sub_app(RenderApp)?;
    let allocator = render.world().get_resource::<MeshAllocator>()?;
    Some((allocator.slabs_size(), allocator.slab_count()))
}

fn soak(name: &str, frames: usize, rendered: bool) {
    // The robot glTF and `cow.mrm`, baked here and re-baked during the session.
    let dir = asset_folder(name);
    bake_cow(&dir, "cow.mrm", 4);
    let mut app = app_with_backends(
        AslodPlugin::default().with_budget(20_000),
        dir.to_str().unwrap(),
        rendered.then_some(Backends::VULKAN),
    );
    let camera = spawn_camera(&mut app, Vec3::new(0.0, 30.0, 60.0));
    if rendered {
        let mut images = app.world_mut().resource_mut::<Assets<Image>>();
        let image = images.add(Image::new_target_texture(
            160,
            90,
            TextureFormat::Rgba8Unorm,
            Some(TextureFormat::Rgba8UnormSrgb),
        ));
        app.world_mut()
            .entity_mut(camera)
            .insert(RenderTarget::Image(image.into()));
        app.world_mut().spawn(DirectionalLight::default());
    }
    app.update();
    let counts = |app: &App| {
        (
            app.world().resource::<Assets<Mesh>>().len(),
            app.world().resource::<Assets<MultiresMesh>>().len(),
        )
    };
    let baseline = counts(&app);
    let allocator_baseline = allocator_bytes(&app);
    assert_eq!(
        allocator_baseline.is_some(),
        rendered,
        "a render world with a mesh allocator exactly when rendered"
    );
    let mut allocator_peak = allocator_baseline;
    let terrain = app
        .world_mut()
        .resource_mut::<Assets<MultiresMesh>>()
        .add(asset());
    let refined = app
        .world_mut()
        .resource_mut::<Assets<MultiresMesh>>()
        .add(cow());
    let mesh = patch(25);
    let partition = Partition::grid(&mesh, GridPlane::XZ, 3, 3).unwrap();
    let terrain_3x3 = app
        .world_mut()
        .resource_mut::<Assets<MultiresMesh>>()
        .add(MultiresMesh::from_indexed(&mesh, &partition).unwrap());
    let baked: Handle<MultiresMesh> = app.world().resource::<AssetServer>().load("cow.mrm");
    let robot = app
        .world()
        .resource::<AssetServer>()
        .load(GltfAssetLabel::Scene(0).from_asset("robot.glb"));
    let mut rebakes = 0;
    // What the plugin said: models ready (by asset) and scenes converted.
    let mut ready_cursor = app
        .world()
        .resource::<Messages<MultiresModelReady>>()
        .get_cursor();
    let mut scene_cursor = app
        .world()
        .resource::<Messages<MultiresSceneConverted>>()
        .get_cursor();
    let (mut ready, mut scenes_converted) = (Vec::new(), 0);
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let mut live: Vec<Entity> = Vec::new();
    let mut budget = 20_000u32;
    let mut allocated = 0;
    let mut warm = None;
    let mut peak_after_warm_up = 0u64;
    for frame in 0..frames {
        if frame == frames / 10 {
            warm = resident_bytes();
        }
        // A camera anywhere around the field, looking somewhere into it.
        let (angle, radius) = (
            rng.unit() * std::f32::consts::TAU,
            10.0 + rng.unit() * 110.0,
        );
        let eye = Vec3::new(
            angle.cos() * radius,
            2.0 + rng.unit() * 60.0,
            angle.sin() * radius,
        );
        let target = Vec3::new(rng.unit() * 60.0 - 30.0, 0.0, rng.unit() * 60.0 - 30.0);
        *app.world_mut().get_mut::<Transform>(camera).unwrap() =
            Transform::from_translation(eye).looking_at(target, Vec3::Y);
        if frame % 5 == 0 && live.len() < 14 {
            let at = Vec3::new(rng.unit() * 60.0 - 30.0, 0.0, rng.unit() * 60.0 - 30.0);
            let material = app
                .world_mut()
                .resource_mut::<Assets<StandardMaterial>>()
                .add(StandardMaterial::default());
            // RobotExpressive cannot lose a triangle (2,412 at every level): at most two
            // scenes keep every model's coarsest levels together under the smallest budget.
            let scenes = live
                .iter()
                .filter(|&&e| app.world().get::<MultiresScene>(e).is_some())
                .count();
            let kind = match rng.below(5) {
                4 if scenes >= 2 => 0,
                kind => kind,
            };
            let mut model = match kind {
                0 => app.world_mut().spawn(MultiresModel(terrain.clone())),
                1 => app
                    .world_mut()
                    .spawn((MultiresModel(terrain.clone()), SharedLevels::default())),
                2 => app
                    .world_mut()
                    .spawn((MultiresModel(refined.clone()), ViewDependent::default())),
                3 => app.world_mut().spawn(MultiresModel(baked.clone())),
                _ => app
                    .world_mut()
                    .spawn((WorldAssetRoot(robot.clone()), MultiresScene::default())),
            };
            model.insert((MeshMaterial3d(material), Transform::from_translation(at)));
            live.push(model.id());
        }
        if frame % 7 == 3 && !live.is_empty() {
            let k = rng.below(live.len() as u64) as usize;
            app.world_mut().entity_mut(live.swap_remove(k)).despawn();
        }
        if frame % 11 == 5 && !live.is_empty() {
            let k = rng.below(live.len() as u64) as usize;
            let material = app
                .world_mut()
                .resource_mut::<Assets<StandardMaterial>>()
                .add(StandardMaterial::from_color(Color::srgb(
                    rng.unit(),
                    0.5,
                    0.5,
                )));
            app.world_mut()
                .entity_mut(live[k])
                .insert(MeshMaterial3d(material));
        }
        if frame % 17 == 9 && !live.is_empty() {
            // Another asset for a region model: it rebuilds.
            let k = rng.below(live.len() as u64) as usize;
            let mut entity = app.world_mut().entity_mut(live[k]);
            if let Some(mut model) = entity.get_mut::<MultiresModel>()
                && (model.0 == terrain || model.0 == terrain_3x3)
            {
                let other = if model.0 == terrain {
                    &terrain_3x3
                } else {
                    &terrain
                };
                model.0 = other.clone();
            }
        }
        if frame % 151 == 75 {
            // `cow.mrm` re-baked with another cut, and reloaded as the file watcher would.
            rebakes += 1;
            bake_cow(&dir, "cow.mrm", if rebakes % 2 == 0 { 4 } else { 12 });
            app.world().resource::<AssetServer>().reload("cow.mrm");
        }
        if frame % 13 == 7 {
            // Well above every model's coarsest level together (at most 14 small models).
            budget = 8_000 + rng.below(60_000) as u32;
            app.world_mut().resource_mut::<PolygonBudget>().total = budget;
        }
        if frame % 97 == 50 {
            // The terrain asset reloaded in place, as a re-baked file would be.
            app.world_mut()
                .resource_mut::<Assets<MultiresMesh>>()
                .insert(terrain.id(), asset())
                .expect("the terrain asset exists");
        }
        app.update();
        if warm.is_some() {
            peak_after_warm_up = peak_after_warm_up.max(resident_bytes().unwrap_or(0));
        }
        let world = app.world();
        let messages = world.resource::<Messages<MultiresModelReady>>();
        ready.extend(ready_cursor.read(messages).map(|m| (frame, m.asset)));
        let messages = world.resource::<Messages<MultiresSceneConverted>>();
        scenes_converted += scene_cursor.read(messages).count();
        allocator_peak = allocator_peak.max(allocator_bytes(&app));
        let stats = *app.world().resource::<AslodStats>();
        if stats.allocated {
            allocated += 1;
            assert!(
                stats.triangles <= u64::from(budget),
                "frame {frame}: {} triangles under P = {budget}",
                stats.triangles
            );
        }
    }
    assert!(
        allocated > frames / 2,
        "the budget was split in {allocated} frames"
    );
    // Every kind took part: scenes converted, baked models shown, and shown again after a
    // re-bake, and models rebuilt on the other terrain asset.
    let shown = |id: AssetId<MultiresMesh>| ready.iter().filter(|(_, a)| *a == id).count();
    assert!(scenes_converted > 0, "no scene was converted");
    assert!(
        shown(terrain_3x3.id()) > 0,
        "no model moved to the other asset"
    );
    let baked_frames: Vec<usize> = ready
        .iter()
        .filter(|(_, a)| *a == baked.id())
        .map(|(f, _)| *f)
        .collect();
    assert!(
        baked_frames.iter().any(|&f| f > 75),
        "no baked model was shown after the first re-bake: {baked_frames:?}"
    );
    println!(
        "soak: {} models ready, {scenes_converted} scenes converted, {rebakes} re-bakes",
        ready.len()
    );
    if let Some(warm) = warm {
        let grown = peak_after_warm_up as f64 / warm as f64 - 1.0;
        println!(
            "soak: {frames} frames, resident {:.1} MB after warm-up, peak {:.1} MB after it ({:+.1}%)",
            warm as f64 / 1e6,
            peak_after_warm_up as f64 / 1e6,
            grown * 100.0
        );
        // Allocator noise dominates short runs; the long run is held to 5%.
        if frames >= 5_000 {
            assert!(grown <= 0.05, "resident memory grew {:.1}%", grown * 100.0);
        }
    }
    for model in live.drain(..) {
        app.world_mut().entity_mut(model).despawn();
    }
    drop((terrain, refined, terrain_3x3, baked, robot));
    // Loads still under way finish, and what nothing holds is dropped (the render world
    // frees a mesh's allocation in the frame after its asset goes).
    for _ in 0..200 {
        app.update();
        if counts(&app) == baseline && allocator_bytes(&app) == allocator_baseline {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    assert_eq!(
        counts(&app),
        baseline,
        "(meshes, multires assets) after everything was despawned"
    );
    if let (Some(before), Some(peak)) = (allocator_baseline, allocator_peak) {
        let after = allocator_bytes(&app).expect("the render world stays");
        println!(
            "soak: mesh allocator {} B in {} slabs before, peak {} B, {} B in {} slabs after",
            before.0, before.1, peak.0, after.0, after.1
        );
        assert!(
            peak.0 > before.0,
            "the session drew nothing through the allocator"
        );
        assert_eq!(
            after, before,
            "mesh allocator (bytes, slabs) after everything was despawned"
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}
