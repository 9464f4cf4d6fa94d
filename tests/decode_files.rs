//! Real HDR/EXR files (every EXR compression, f16 and f32, NaN/Inf, all half values, 1e36
//! values, old RLE), malformed files, truncated and corrupted copies: typed errors, never a
//! panic, and the right pixel statistics.

mod common;
use common::reference;
use goniowatch::decode::{decode, CaptureFormat, DecodeError, DecodeLimits};
use goniowatch::fixtures::Rng;
use goniowatch::measure::averaging::{average, AverageOptions, CaptureStats, Roi};

fn read(name: &str) -> Vec<u8> {
    std::fs::read(reference(&format!("images/{name}"))).unwrap()
}

fn stats(name: &str) -> CaptureStats {
    let img = decode(&read(name), &DecodeLimits::default()).unwrap();
    average(&img.view(), &AverageOptions::default()).unwrap()
}

const VALID: &[&str] = &[
    "valid/AllHalfValues.exr",
    "valid/BrightRingsNanInf.exr",
    "valid/Desk.exr",
    "valid/f16_b44.exr",
    "valid/f16_piz.exr",
    "valid/f16_zip.exr",
    "valid/f32_b44.exr",
    "valid/f32_dwaa.exr",
    "valid/f32_piz.exr",
    "valid/f32_pxr24.exr",
    "valid/f32_rle.exr",
    "valid/f32_uncompressed.exr",
    "valid/f32_zip.exr",
    "valid/image1.hdr",
    "valid/old-rle.hdr",
    "valid/overexposed_gradient.hdr",
    "valid/rgbr4x4.hdr",
    "valid/scale.hdr",
];

#[test]
fn every_valid_file_decodes_with_the_right_format() {
    for name in VALID {
        let img =
            decode(&read(name), &DecodeLimits::default()).unwrap_or_else(|e| panic!("{name}: {e}"));
        let want = if name.ends_with(".exr") {
            CaptureFormat::Exr
        } else {
            CaptureFormat::Hdr
        };
        assert_eq!(img.format, want);
        assert_eq!(img.samples().count(), img.width * img.height * 3);
        let s = average(&img.view(), &AverageOptions::default()).unwrap();
        assert!(s.mean_rgb.iter().all(|v| v.is_finite()), "{name}");
    }
}

#[test]
fn lossless_compressions_give_identical_means() {
    let reference_mean = stats("valid/f32_uncompressed.exr").mean_rgb;
    for name in [
        "valid/f32_zip.exr",
        "valid/f32_piz.exr",
        "valid/f32_rle.exr",
    ] {
        assert_eq!(stats(name).mean_rgb, reference_mean, "{name}");
    }
    assert_eq!(
        stats("valid/f16_piz.exr").mean_rgb,
        stats("valid/f16_zip.exr").mean_rgb
    );
    // lossy ones stay close
    for name in [
        "valid/f32_pxr24.exr",
        "valid/f32_b44.exr",
        "valid/f32_dwaa.exr",
        "valid/f16_b44.exr",
    ] {
        let m = stats(name).mean_rgb;
        for c in 0..3 {
            assert!(
                (m[c] / reference_mean[c] - 1.0).abs() < 0.06,
                "{name}: {m:?}"
            );
        }
    }
}

#[test]
fn all_half_values_including_denormals_nan_and_inf() {
    // the file holds every one of the 65,536 half-float bit patterns, one per pixel
    let s = stats("valid/AllHalfValues.exr");
    assert_eq!(s.pixels, 65_536);
    // exponent all ones: 2 infinities + 2,046 NaNs
    assert_eq!(s.nonfinite, 2_048);
    // negative finite patterns: 32,768 − 1,024 non-finite − (−0)
    assert_eq!(s.negative, 31_743);
    // ±65504 are the largest finite halves; +65504 reaches the default clip level
    assert_eq!(s.clipped, 1);
    assert_eq!(s.max_value, 65504.0);
    // every finite value appears with both signs: the mean is exactly zero
    assert_eq!(s.mean_rgb, [0.0, 0.0, 0.0]);
    // denormals survive the f16 → f32 → f64 path: the smallest positive one is 2^-24
    let img = decode(&read("valid/AllHalfValues.exr"), &DecodeLimits::default()).unwrap();
    let smallest = img
        .samples()
        .filter(|v| *v > 0.0)
        .fold(f32::INFINITY, f32::min);
    assert_eq!(smallest, 2f32.powi(-24));
}

#[test]
fn nan_and_inf_pixels_are_counted_and_excluded() {
    let s = stats("valid/BrightRingsNanInf.exr");
    assert_eq!(s.nonfinite, 12);
    assert_eq!(s.pixels, 800 * 800);
    assert!(s.mean_rgb.iter().all(|v| v.is_finite() && *v > 0.0));
}

#[test]
fn values_near_1e36_do_not_overflow() {
    let img = decode(&read("valid/scale.hdr"), &DecodeLimits::default()).unwrap();
    let s = average(&img.view(), &AverageOptions::default()).unwrap();
    assert!(s.max_value > 1e36, "{}", s.max_value);
    assert!(s.mean_rgb.iter().all(|v| v.is_finite()));
    // an f32 accumulator overflows on the same data
    let blue_f32: Vec<f32> = (0..img.height)
        .flat_map(|y| (0..img.width).map(move |x| (x, y)))
        .map(|(x, y)| img.pixel(x, y).unwrap()[2])
        .collect();
    let f32_sum: f32 = blue_f32.iter().sum();
    assert!(f32_sum.is_infinite());
    // the f64 row-wise sum agrees with an exactly rounded reference (sorted pairwise in f64)
    let mut blue: Vec<f64> = blue_f32.iter().map(|&v| v as f64).collect();
    blue.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let exact: f64 = blue.iter().sum::<f64>() / blue.len() as f64;
    assert!((s.mean_rgb[2] / exact - 1.0).abs() < 1e-14);
    assert!(s.clipped > 0, "values above the clip level are flagged");
}

#[test]
fn region_of_interest_excludes_the_holder() {
    let img = decode(&read("valid/Desk.exr"), &DecodeLimits::default()).unwrap();
    let full = average(&img.view(), &AverageOptions::default()).unwrap();
    let inner = average(
        &img.view(),
        &AverageOptions {
            roi: Roi::Margin { pixels: 100 },
            ..AverageOptions::default()
        },
    )
    .unwrap();
    assert_eq!(inner.pixels, ((644 - 200) * (874 - 200)) as u64);
    assert_ne!(inner.mean_rgb, full.mean_rgb);
    let rect = average(
        &img.view(),
        &AverageOptions {
            roi: Roi::Rect {
                x: 100,
                y: 100,
                width: 444,
                height: 674,
            },
            ..AverageOptions::default()
        },
    )
    .unwrap();
    assert_eq!(rect, inner);
}

#[test]
fn file_without_rgb_channels_is_a_clear_error() {
    let e = decode(&read("valid/WideFloatRange.exr"), &DecodeLimits::default()).unwrap_err();
    assert!(matches!(e, DecodeError::NoRgbLayer(_)), "{e}");
    assert!(e.to_string().contains("no layer with R, G and B"));
}

#[test]
fn malformed_exr_files_give_typed_errors() {
    for name in [
        "invalid/comp_bad_pos_bounds_piz.exr",
        "invalid/comp_early_eof_piz.exr",
        "invalid/comp_short_decode_piz.exr",
        "invalid/invalid_integer_bounds.exr",
    ] {
        let e = decode(&read(name), &DecodeLimits::default());
        assert!(
            matches!(
                e,
                Err(DecodeError::Exr(_))
                    | Err(DecodeError::Panicked(_))
                    | Err(DecodeError::TooLarge { .. })
            ),
            "{name}: {e:?}"
        );
    }
}

#[test]
fn truncated_copies_of_every_valid_file_never_panic() {
    for name in VALID {
        let bytes = read(name);
        let n = bytes.len();
        for cut in [
            0,
            1,
            2,
            4,
            8,
            16,
            64,
            200,
            n / 4,
            n / 2,
            n * 3 / 4,
            n - 100.min(n),
            n - 1,
        ] {
            let r = decode(&bytes[..cut.min(n)], &DecodeLimits::default());
            if cut == 0 {
                assert_eq!(r, Err(DecodeError::Empty));
            }
            // a Radiance file cut at a scanline boundary may still decode partially; anything
            // else must be an error, and nothing may panic past `decode`
            if let Ok(img) = &r {
                assert_eq!(
                    img.samples().count(),
                    img.width * img.height * 3,
                    "{name} cut at {cut}"
                );
            }
        }
    }
}

#[test]
fn corrupted_bytes_never_panic() {
    let mut rng = Rng(99);
    for name in VALID {
        let orig = read(name);
        for _ in 0..20 {
            let mut b = orig.clone();
            let flips = 1 + (rng.next_u64() % 16) as usize;
            for _ in 0..flips {
                let i = (rng.next_u64() as usize) % b.len();
                b[i] ^= 1 << (rng.next_u64() % 8);
            }
            let _ = decode(&b, &DecodeLimits::default());
        }
    }
}

#[test]
fn garbage_and_unknown_formats() {
    assert!(matches!(
        decode(b"P6\n2 2\n255\n", &DecodeLimits::default()),
        Err(DecodeError::UnknownFormat(_))
    ));
    assert!(matches!(
        decode(b"#?RADIANCE\n\n-Y 2 +X 2\n", &DecodeLimits::default()),
        Err(DecodeError::Hdr(_))
    ));
    assert!(matches!(
        decode(
            &[0x76, 0x2f, 0x31, 0x01, 2, 0, 0, 0],
            &DecodeLimits::default()
        ),
        Err(DecodeError::Exr(_))
    ));
}

#[test]
fn oversized_headers_are_refused_before_allocation() {
    // Radiance: a header that claims 100,000 × 100,000 pixels
    let hdr = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 100000 +X 100000\n\x02\x02\x00\x00";
    assert!(
        matches!(
            decode(hdr, &DecodeLimits::default()),
            Err(DecodeError::TooLarge { .. })
        ),
        "{:?}",
        decode(hdr, &DecodeLimits::default())
    );
    // OpenEXR: patch the dataWindow of a real file to 200,000 × 200,000
    let mut b = read("valid/f32_uncompressed.exr");
    let key = b"dataWindow\0box2i\0";
    let at = b.windows(key.len()).position(|w| w == key).unwrap() + key.len() + 4;
    b[at + 8..at + 12].copy_from_slice(&199_999i32.to_le_bytes());
    b[at + 12..at + 16].copy_from_slice(&199_999i32.to_le_bytes());
    let r = decode(&b, &DecodeLimits::default());
    assert!(
        matches!(
            r,
            Err(DecodeError::TooLarge { .. }) | Err(DecodeError::Exr(_))
        ),
        "{r:?}"
    );
    // and a small limit refuses a real file
    let small = DecodeLimits {
        max_pixels: 1000,
        max_dimension: 100,
        threads: 1,
        ..DecodeLimits::default()
    };
    assert!(matches!(
        decode(&read("valid/Desk.exr"), &small),
        Err(DecodeError::TooLarge { .. })
    ));
    assert!(matches!(
        decode(&read("valid/old-rle.hdr"), &small),
        Err(DecodeError::TooLarge { .. })
    ));
}

#[test]
fn threaded_exr_decoding_gives_the_same_pixels() {
    for name in VALID.iter().filter(|n| n.ends_with(".exr")) {
        let bytes = read(name);
        let one = decode(
            &bytes,
            &DecodeLimits {
                threads: 1,
                ..DecodeLimits::default()
            },
        )
        .unwrap();
        let two = decode(
            &bytes,
            &DecodeLimits {
                threads: 2,
                ..DecodeLimits::default()
            },
        )
        .unwrap();
        // compare bit patterns so NaN pixels count as equal
        let bits = |d: &goniowatch::decode::DecodedImage| {
            d.samples().map(f32::to_bits).collect::<Vec<_>>()
        };
        assert_eq!(bits(&one), bits(&two), "{name}");
    }
    // and malformed files fail the same way on several threads
    for name in [
        "invalid/comp_bad_pos_bounds_piz.exr",
        "invalid/comp_short_decode_piz.exr",
    ] {
        assert!(decode(
            &read(name),
            &DecodeLimits {
                threads: 4,
                ..DecodeLimits::default()
            }
        )
        .is_err());
    }
}
