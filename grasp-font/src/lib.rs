//! The one font of the toolkit's pictures: DejaVu Sans, compiled into the
//! programs (the `dejavu` crate), so that every machine labels its pictures
//! the same way and none needs a system font. The generator's drawings
//! (catalog sheets, planned paths) draw with [`draw_text`]; the trainer's
//! plots register [`bytes`] with plotters.

use ab_glyph::{Font, FontRef, Glyph, PxScale, ScaleFont};
use image::{Rgb, RgbImage};
use std::sync::OnceLock;

/// The font file's bytes (TrueType).
pub fn bytes() -> &'static [u8] {
    dejavu::sans::regular()
}

fn font() -> &'static FontRef<'static> {
    static FONT: OnceLock<FontRef<'static>> = OnceLock::new();
    FONT.get_or_init(|| FontRef::try_from_slice(bytes()).expect("the bundled font parses"))
}

/// Draws `text` with its line box's top-left corner at (`x`, `y`), `px`
/// pixels from ascender to descender, blending `colour` over the image by
/// glyph coverage. Pixels outside the image are left out.
pub fn draw_text(img: &mut RgbImage, x: i64, y: i64, text: &str, colour: Rgb<u8>, px: f32) {
    let scaled = font().as_scaled(PxScale::from(px));
    let baseline = y as f32 + scaled.ascent();
    let mut caret = x as f32;
    let mut previous = None;
    for ch in text.chars() {
        let id = scaled.glyph_id(ch);
        if let Some(p) = previous {
            caret += scaled.kern(p, id);
        }
        let glyph: Glyph = id.with_scale_and_position(px, ab_glyph::point(caret, baseline));
        caret += scaled.h_advance(id);
        previous = Some(id);
        let Some(outline) = font().outline_glyph(glyph) else {
            continue; // a space
        };
        let bounds = outline.px_bounds();
        outline.draw(|gx, gy, coverage| {
            let (px_x, px_y) = (
                bounds.min.x as i64 + i64::from(gx),
                bounds.min.y as i64 + i64::from(gy),
            );
            if px_x < 0 || px_y < 0 || px_x >= i64::from(img.width()) {
                return;
            }
            if px_y >= i64::from(img.height()) {
                return;
            }
            let a = coverage.clamp(0.0, 1.0);
            let pixel = img.get_pixel_mut(px_x as u32, px_y as u32);
            for (c, t) in pixel.0.iter_mut().zip(colour.0) {
                *c = (f32::from(*c) * (1.0 - a) + f32::from(t) * a).round() as u8;
            }
        });
    }
}

/// The width in pixels of `text` at `px` pixels.
pub fn text_width(text: &str, px: f32) -> f32 {
    let scaled = font().as_scaled(PxScale::from(px));
    let mut width = 0.0;
    let mut previous = None;
    for ch in text.chars() {
        let id = scaled.glyph_id(ch);
        if let Some(p) = previous {
            width += scaled.kern(p, id);
        }
        width += scaled.h_advance(id);
        previous = Some(id);
    }
    width
}

#[cfg(test)]
mod tests {
    use super::*;

    fn inked(img: &RgbImage) -> usize {
        img.pixels().filter(|p| p.0 != [255, 255, 255]).count()
    }

    #[test]
    fn text_puts_ink_inside_its_box_and_nowhere_else() {
        let mut img = RgbImage::from_pixel(200, 40, Rgb([255, 255, 255]));
        draw_text(&mut img, 10, 5, "Power grasp 42%", Rgb([0, 0, 0]), 16.0);
        let width = text_width("Power grasp 42%", 16.0);
        assert!(width > 80.0 && width < 160.0, "{width}");
        assert!(inked(&img) > 150, "{}", inked(&img));
        for (x, y, p) in img.enumerate_pixels() {
            if p.0 != [255, 255, 255] {
                assert!(x >= 10 && (x as f32) <= 11.0 + width, "ink at x {x}");
                assert!((5..5 + 17).contains(&y), "ink at y {y}");
            }
        }
        // Letters differ: two strings of one length draw different pixels.
        let mut other = RgbImage::from_pixel(200, 40, Rgb([255, 255, 255]));
        draw_text(&mut other, 10, 5, "Pinch grasp 17%", Rgb([0, 0, 0]), 16.0);
        assert_ne!(img, other);
    }

    #[test]
    fn text_off_the_image_is_clipped_without_panicking() {
        let mut img = RgbImage::from_pixel(20, 10, Rgb([255, 255, 255]));
        draw_text(&mut img, -30, -8, "clipped text", Rgb([0, 0, 0]), 30.0);
        draw_text(&mut img, 15, 5, "clipped text", Rgb([0, 0, 0]), 30.0);
        assert!(inked(&img) > 0);
    }

    #[test]
    fn the_bundled_font_is_a_truetype_file() {
        assert_eq!(&bytes()[..4], &[0, 1, 0, 0]);
        assert!(font().glyph_id('A').0 != 0 && font().glyph_id('%').0 != 0);
    }
}
