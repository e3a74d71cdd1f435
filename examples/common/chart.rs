//! Charts drawn with `plotters` into an RGB buffer and saved as PNG, with Bevy's built-in font.

use bevy::asset::RenderAssetUsages;
use bevy::image::Image;
use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat};
use plotters::prelude::*;
use std::path::Path;
use std::sync::Once;

/// Every chart's size in pixels.
pub const SIZE: (u32, u32) = (960, 540);

/// Plotters draws text with a font it is given: Bevy's built-in one.
fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        if plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            bevy::text::DEFAULT_FONT_DATA,
        )
        .is_err()
        {
            bevy::log::warn!("the chart font did not load; charts have no text");
        }
    });
}

fn save(path: &Path, rgb: &[u8]) -> Result<(), String> {
    let rgba: Vec<u8> = rgb
        .chunks_exact(3)
        .flat_map(|p| [p[0], p[1], p[2], 255])
        .collect();
    let image = Image::new(
        Extent3d {
            width: SIZE.0,
            height: SIZE.1,
            depth_or_array_layers: 1,
        },
        TextureDimension::D2,
        rgba,
        TextureFormat::Rgba8UnormSrgb,
        RenderAssetUsages::default(),
    );
    image
        .try_into_dynamic()
        .map_err(|e| e.to_string())?
        .to_rgb8()
        .save(path)
        .map_err(|e| format!("{}: {e}", path.display()))
}

/// Draws a chart with `body` and saves it as a PNG at `path`.
pub fn draw(
    path: &Path,
    body: impl FnOnce(&DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>) -> Result<(), String>,
) -> Result<(), String> {
    register_font();
    let mut rgb = vec![0u8; (SIZE.0 * SIZE.1 * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        body(&root)?;
        root.present().map_err(|e| e.to_string())?;
    }
    save(path, &rgb)
}
