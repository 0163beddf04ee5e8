//! OpenEXR output: written atomically, re-read by our reader and by the `exr` crate's generic
//! reader, with channels and metadata intact.

use gantry_hal::{BayerFrame, BayerPattern};
use hdr::ExrCompression;
use hdr::{
    hdr_path, merge, read_exr, thesis_ladder, truth_path, write_hdr_exr, write_truth_exr,
    DefectMap, ExrOptions, HdrError, Intercept, MergeOptions, PositionInfo,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A 37 × 23 series from a small noisy sensor model of our own (Poisson-like Gaussian shot
/// noise, read noise, black level 4 DN), rates log-uniform over 7 decades.
fn noisy_image(intercept: Intercept) -> hdr::HdrImage {
    let (w, h) = (37, 23);
    let mut rng = ChaCha8Rng::seed_from_u64(42);
    let rates: Vec<f64> = (0..w * h)
        .map(|_| 10f64.powf(rng.gen_range(-0.5..6.8)))
        .collect();
    let frames: Vec<BayerFrame> = thesis_ladder()
        .iter()
        .enumerate()
        .map(|(k, &t)| {
            let data = rates
                .iter()
                .map(|&r| {
                    let s = r * t;
                    let n: f64 = rng.sample(rand_distr::StandardNormal);
                    (4.0 + s + (s / 17.0 + 0.5).sqrt() * n)
                        .round()
                        .clamp(0.0, 1023.0) as u16
                })
                .collect();
            BayerFrame::new(
                w,
                h,
                10,
                BayerPattern::Rggb,
                data,
                t,
                k as f64,
                25.0,
                k as u64,
            )
            .unwrap()
        })
        .collect();
    let mut mask = vec![false; w * h];
    mask[5] = true;
    mask[w * h - 1] = true;
    let defects = DefectMap::from_mask(w, h, mask).unwrap();
    merge(
        &frames,
        Some(&defects),
        &MergeOptions {
            intercept,
            ..Default::default()
        },
    )
    .unwrap()
}

fn same_f32(a: &[f32], b: &[f32]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

#[test]
fn hdr_files_round_trip_with_channels_and_metadata() {
    let dir = tempfile::tempdir().unwrap();
    for (intercept, compression) in [
        (Intercept::Fitted, ExrCompression::Zip),
        (Intercept::BlackLevel(4.0), ExrCompression::None),
        (Intercept::Fitted, ExrCompression::Rle),
    ] {
        let img = noisy_image(intercept);
        assert!(img.valid_count() > 300);
        let info = PositionInfo {
            index: Some(7),
            angle_deg: Some(93.5),
            sensor_temperature_c: Some(25.25),
            timestamp_s: Some(1234.5),
        };
        let path = hdr_path(dir.path(), 7);
        assert!(path.ends_with("hdr/007.exr"));
        let opts = ExrOptions {
            fit_statistics: true,
            compression,
        };
        write_hdr_exr(&path, &img, &info, &opts).unwrap();
        let f = read_exr(&path).unwrap();
        assert_eq!((f.width, f.height), (img.width, img.height));
        assert_eq!(f.kind, "radiance");
        assert!(same_f32(&f.radiance, &img.radiance));
        assert_eq!(f.valid.as_ref().unwrap(), &img.valid);
        assert_eq!(f.count.as_ref().unwrap(), &img.count);
        assert_eq!(f.flags.as_ref().unwrap(), &img.flags);
        assert!(same_f32(f.std_error.as_ref().unwrap(), &img.std_error));
        assert!(same_f32(f.correlation.as_ref().unwrap(), &img.correlation));
        assert_eq!(f.exposures_s, img.exposures_s);
        assert_eq!(f.merge_options.as_ref().unwrap(), &img.options);
        assert_eq!(f.hot_pixels, Some(2));
        assert_eq!(f.position, info);
    }
    // Only the final file is left behind (the temporary one was renamed).
    let names: Vec<String> = std::fs::read_dir(dir.path().join("hdr"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, vec!["007.exr".to_string()]);
}

#[test]
fn files_are_plain_single_part_float_exr() {
    // Read with the exr crate's generic reader, as any OpenEXR tool would.
    let dir = tempfile::tempdir().unwrap();
    let img = noisy_image(Intercept::Fitted);
    let path = hdr_path(dir.path(), 0);
    let lean = ExrOptions {
        fit_statistics: false,
        ..Default::default()
    };
    write_hdr_exr(&path, &img, &PositionInfo::default(), &lean).unwrap();
    let any = exr::prelude::read_all_data_from_file(&path).unwrap();
    assert_eq!(any.layer_data.len(), 1);
    let layer = &any.layer_data[0];
    let names: Vec<String> = layer
        .channel_data
        .list
        .iter()
        .map(|c| c.name.to_string())
        .collect();
    assert_eq!(names, vec!["count", "radiance", "valid"]);
    // Radiance in f32; the whole-number channels in f16, which holds them exactly.
    for c in &layer.channel_data.list {
        let float = c.name.to_string() == "radiance";
        match &c.sample_data {
            exr::prelude::Levels::Singular(exr::prelude::FlatSamples::F32(_)) => assert!(float),
            exr::prelude::Levels::Singular(exr::prelude::FlatSamples::F16(v)) => {
                assert!(!float);
                assert!(v
                    .iter()
                    .all(|x| x.to_f32().fract() == 0.0 && x.to_f32() >= 0.0));
            }
            other => panic!("channel {} has samples {other:?}", c.name),
        }
    }
    assert_eq!(layer.size.width(), 37);
    // Metadata is in the header.
    let meta = exr::meta::MetaData::read_from_file(&path, false).unwrap();
    let attrs = &meta.headers[0].own_attributes.other;
    assert!(attrs.contains_key(&exr::prelude::Text::from("exposures_s")));
    assert!(read_exr(&path).unwrap().std_error.is_none());
}

#[test]
fn truth_files_hold_radiance_in_the_same_units() {
    let dir = tempfile::tempdir().unwrap();
    let rate: Vec<f32> = (0..12).map(|i| 0.5 * 3f32.powi(i)).collect();
    let path = truth_path(dir.path(), 12);
    assert!(path.ends_with("truth/012.exr"));
    let info = PositionInfo {
        index: Some(12),
        ..Default::default()
    };
    write_truth_exr(&path, 4, 3, &rate, &info).unwrap();
    let f = read_exr(&path).unwrap();
    assert_eq!(f.kind, "truth");
    assert_eq!(f.radiance, rate);
    assert!(f.valid.is_none() && f.merge_options.is_none());
    assert_eq!(f.position.index, Some(12));
    assert!(matches!(
        write_truth_exr(&path, 5, 3, &rate, &info),
        Err(HdrError::Dimensions(_))
    ));
}

#[test]
fn unreadable_files_are_typed_errors() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("nope.exr");
    assert!(matches!(read_exr(&missing), Err(HdrError::Io { .. })));
    let junk = dir.path().join("junk.exr");
    std::fs::write(&junk, b"this is not an OpenEXR file at all").unwrap();
    assert!(matches!(read_exr(&junk), Err(HdrError::Exr { .. })));
}

/// Found by the `exr` fuzz target: a 742-byte file whose data window spans 4 × 4,160,749,313
/// lines made the decoder ask for 2 GB before reading a pixel. The headers are now checked
/// against the sample budget and the file's length first.
#[test]
fn a_header_announcing_a_huge_image_is_refused_before_any_allocation() {
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/hostile_huge_window.exr");
    match read_exr(&p) {
        Err(HdrError::Exr { detail, .. }) => {
            assert!(detail.contains("more than"), "{detail}");
        }
        other => panic!("{other:?}"),
    }
    // The budget leaves every file the job writes readable (a round trip is above).
    const { assert!(hdr::MAX_EXR_SAMPLE_BYTES >= 4 * 4096 * 4096 * 4) };
}

/// A 742-byte ZIP-compressed file (found by the `exr` fuzz target) whose data window announces
/// just under the sample budget: it used to make the decoder allocate 2 GB and take seconds.
/// No deflate stream expands more than 1,032 times, so the file cannot hold those samples.
#[test]
fn a_header_announcing_more_samples_than_the_file_can_hold_is_refused() {
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/hostile_unbacked_window.exr");
    assert_eq!(std::fs::metadata(&p).unwrap().len(), 742);
    match read_exr(&p) {
        Err(HdrError::Exr { detail, .. }) => {
            assert!(detail.contains("can hold"), "{detail}");
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn files_from_the_reference_openexr_library_are_read() {
    // Written by tools/hdr/make_fixture.py with the OpenEXR Python bindings.
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/openexr_python.exr");
    let f = read_exr(&path).unwrap();
    assert_eq!((f.width, f.height), (4, 3));
    assert_eq!(f.kind, "radiance");
    for i in 0..12 {
        assert_eq!(f.radiance[i], (0.5 * 3f64.powi(i as i32)) as f32);
        assert_eq!(f.valid.as_ref().unwrap()[i], i % 2 == 1);
        assert_eq!(f.count.as_ref().unwrap()[i] as usize, i);
    }
    assert_eq!(f.exposures_s, vec![0.001, 0.01, 0.1]);
    let m = f.merge_options.unwrap();
    assert_eq!((m.low_dn, m.high_dn, m.min_valid), (10.0, 1000.0, 3));
    assert!((m.min_correlation - 0.998).abs() < 1e-6);
    assert_eq!(m.intercept, Intercept::Fitted);
    assert_eq!(f.position.index, Some(5));
    assert_eq!(f.position.angle_deg, Some(42.5));
}
