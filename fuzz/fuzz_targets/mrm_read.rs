//! The `.mrm` reader on arbitrary bytes, within [`LoadLimits::SMALL`]: it must return an
//! error or assets that every polygon and region cache can use at any level, never panic,
//! and stay within the limits' memory bound.
//!
//! `cargo +nightly fuzz run mrm_read fuzz/seeds -- -max_total_time=300 -rss_limit_mb=1024`
//! (from the crate's root; the seeds are files the crate baked).
#![no_main]

use bevy_aslod::mesh::LoadLimits;
use bevy_aslod::mrm;
use bevy_aslod::multires::PolygonCache;
use bevy_aslod::regions::RegionCaches;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(pm) = mrm::read_progressive_with_limits(data, &LoadLimits::SMALL) {
        let mut cache = PolygonCache::new(&pm);
        for level in (0..pm.level_count()).rev().step_by(5) {
            cache.set_level(&pm, level);
        }
    }
    if let Ok(file) = mrm::read_with_limits(data, &LoadLimits::SMALL) {
        let mut seed = data.len() as u64 | 1;
        let mut out = Vec::new();
        for (_, baked) in &file.meshes {
            let regions = &baked.regions;
            let mut caches = RegionCaches::new(regions);
            for _ in 0..2 {
                for (r, region) in regions.regions().iter().enumerate() {
                    seed ^= seed << 13;
                    seed ^= seed >> 7;
                    seed ^= seed << 17;
                    let count = (seed % (region.max_triangles() as u64 + 1)) as usize;
                    caches.set_triangle_count(regions, r, count);
                }
                for r in 0..regions.regions().len() {
                    caches.write_global_indices(regions, r, &mut out);
                }
            }
        }
    }
});
