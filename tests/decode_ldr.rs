//! Low-dynamic-range captures (PNG 8 and 16 bit, JPEG): the sRGB transfer function undone,
//! grey and alpha handled, saturated codes counted as clipped, and damaged files refused with a
//! typed error, never a panic. The files are written here with the `image` crate's encoders.

use goniowatch::daemon::ingest::average_decoded;
use goniowatch::decode::{decode, required_bytes, CaptureFormat, DecodeError, DecodeLimits};
use goniowatch::measure::averaging::AverageOptions;
use image::{ExtendedColorType, ImageEncoder};

/// The IEC 61966-2-1 decoding function, in f64.
fn srgb(v: f64) -> f64 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

fn png(w: u32, h: u32, data: &[u8], colour: ExtendedColorType) -> Vec<u8> {
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new(&mut out)
        .write_image(data, w, h, colour)
        .unwrap();
    out
}

#[test]
fn eight_bit_png_codes_are_linearised() {
    // a 3 × 1 RGB image: black, mid grey, white-ish with distinct channels
    let data = [0u8, 0, 0, 128, 128, 128, 255, 64, 10];
    let img = decode(
        &png(3, 1, &data, ExtendedColorType::Rgb8),
        &DecodeLimits::default(),
    )
    .unwrap();
    assert_eq!(img.format, CaptureFormat::Png);
    assert_eq!((img.width, img.height), (3, 1));
    for (k, &code) in data.iter().enumerate() {
        let px = img.pixel(k / 3, 0).unwrap()[k % 3] as f64;
        assert!(
            (px - srgb(code as f64 / 255.0)).abs() < 1e-6,
            "code {code}: {px}"
        );
    }
    assert_eq!(
        img.pixel(2, 0).unwrap()[0],
        1.0,
        "a saturated code reads exactly 1"
    );
}

#[test]
fn sixteen_bit_grey_and_alpha_pngs() {
    // 16-bit grey: R = G = B (the encoder takes native-endian samples)
    let codes = [0u16, 32768, 65535];
    let be: Vec<u8> = codes.iter().flat_map(|c| c.to_ne_bytes()).collect();
    let img = decode(
        &png(3, 1, &be, ExtendedColorType::L16),
        &DecodeLimits::default(),
    )
    .unwrap();
    for (x, &c) in codes.iter().enumerate() {
        let p = img.pixel(x, 0).unwrap();
        assert!(p[0] == p[1] && p[1] == p[2]);
        assert!(
            (p[0] as f64 - srgb(c as f64 / 65535.0)).abs() < 1e-6,
            "{c}: {p:?}"
        );
    }
    // RGBA: alpha is dropped
    let rgba = [10u8, 20, 30, 0, 200, 100, 50, 255];
    let img = decode(
        &png(2, 1, &rgba, ExtendedColorType::Rgba8),
        &DecodeLimits::default(),
    )
    .unwrap();
    assert!((img.pixel(0, 0).unwrap()[2] as f64 - srgb(30.0 / 255.0)).abs() < 1e-6);
    assert!((img.pixel(1, 0).unwrap()[0] as f64 - srgb(200.0 / 255.0)).abs() < 1e-6);
}

#[test]
fn saturated_codes_are_counted_as_clipped_whatever_the_hdr_clip_level() {
    let mut data = vec![100u8; 8 * 8 * 3];
    for px in data.chunks_exact_mut(3).take(5) {
        px[1] = 255;
    }
    let img = decode(
        &png(8, 8, &data, ExtendedColorType::Rgb8),
        &DecodeLimits::default(),
    )
    .unwrap();
    let opts = AverageOptions {
        clip_level: 60000.0,
        ..AverageOptions::default()
    };
    let s = average_decoded(&img, &opts).unwrap();
    assert_eq!(s.clipped, 5);
    assert_eq!(s.pixels, 64);
}

#[test]
fn a_uniform_jpeg_reads_its_linear_value() {
    let data = vec![128u8; 16 * 16 * 3];
    let mut out = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, 95)
        .write_image(&data, 16, 16, ExtendedColorType::Rgb8)
        .unwrap();
    let img = decode(&out, &DecodeLimits::default()).unwrap();
    assert_eq!(img.format, CaptureFormat::Jpeg);
    let s = average_decoded(&img, &AverageOptions::default()).unwrap();
    let want = srgb(128.0 / 255.0);
    for c in s.mean_rgb {
        assert!((c - want).abs() < 0.01 * want, "{c} vs {want}");
    }
}

#[test]
fn damaged_ldr_files_are_typed_errors() {
    let data = vec![77u8; 32 * 32 * 3];
    let whole = png(32, 32, &data, ExtendedColorType::Rgb8);
    let limits = DecodeLimits::default();
    for cut in [9, 20, 40, whole.len() / 2, whole.len() - 5] {
        let e = decode(&whole[..cut], &limits).unwrap_err();
        assert!(matches!(e, DecodeError::Ldr { .. }), "cut {cut}: {e}");
    }
    let mut flipped = whole.clone();
    let n = flipped.len();
    flipped[n / 2] ^= 0x55;
    assert!(decode(&flipped, &limits).is_err());
    let jpeg_head = [0xffu8, 0xd8, 0xff, 0xe0, 0, 16, b'J', b'F'];
    assert!(matches!(
        decode(&jpeg_head, &limits).unwrap_err(),
        DecodeError::Ldr { format: "JPEG", .. }
    ));
    // a budget too small for the image is refused before the pixels are decoded
    let small = DecodeLimits {
        max_bytes: 1000,
        ..limits
    };
    assert!(matches!(
        decode(&whole, &small).unwrap_err(),
        DecodeError::OverBudget { .. }
    ));
    assert!(required_bytes(&whole, &limits).unwrap() >= 32 * 32 * 12);
}
