//! Malformed answers of the devices give typed errors, whose kind is what a retry policy
//! decides on, and never a panic.

use gantry_hal::grbl::{error_kind, parse_status, Response};
use gantry_hal::{
    decode_frames, encode_frames, pack_bayer10, unpack_bayer10, Bayer10Format, BayerFrame,
    BayerPattern, DeviceKind, ErrorKind, HalError, RigConfig,
};

#[test]
fn garbled_status_reports_are_protocol_errors() {
    for line in [
        "",
        "<",
        "<>",
        "Idle|MPos:0,0,0",
        "<Idle|MPos:0,0,0",
        "<Dancing|MPos:0,0,0>",
        "<Idle|FS:0,0>",
        "<Idle|MPos:1.0,x,0>",
        "<Idle|MPos:NaN,0,0>",
        "<Idle|MPos:inf,0,0>",
        "<Idle|MPos>",
        "<Idle|MPos:1,2,3|garbage>",
    ] {
        let e = parse_status(line).expect_err(line);
        assert!(matches!(e, HalError::Protocol { .. }), "{line}: {e}");
        assert_eq!(e.kind(), ErrorKind::Protocol, "{line}");
    }
    let ok = parse_status("<Idle|WPos:12.500,0.000,0.000|FS:0,0|A:SF>").unwrap();
    assert_eq!(ok.position, vec![12.5, 0.0, 0.0]);
    assert!(ok.is_work_position && ok.spindle_on && ok.flood_on);
}

#[test]
fn odd_controller_lines_are_classified_not_trusted() {
    assert_eq!(Response::classify("error:"), Response::Error(0));
    assert_eq!(Response::classify("error:abc"), Response::Error(0));
    assert_eq!(Response::classify("error:9999"), Response::Error(0));
    assert_eq!(Response::classify("ALARM:x"), Response::Alarm(0));
    assert_eq!(Response::classify("\u{0}\u{7f}ok\r\n"), Response::Ok);
    // Non-ASCII bytes are line noise (a GRBL controller never sends them).
    assert_eq!(Response::classify("oké"), Response::Ok);
    assert_eq!(Response::classify("okay"), Response::Other("okay".into()));
    let long = "x".repeat(10_000);
    match Response::classify(&long) {
        Response::Other(s) => assert_eq!(s.len(), gantry_hal::grbl::MAX_LINE),
        other => panic!("{other:?}"),
    }
}

#[test]
fn grbl_error_codes_map_to_kinds() {
    let e = |code| HalError::GrblError {
        code,
        message: gantry_hal::grbl::error_message(code).into(),
        command: "G0 X1".into(),
    };
    // error:9 (G-code locked out after an alarm or a reset): home first.
    assert_eq!(error_kind(9), ErrorKind::NeedsHoming);
    assert_eq!(e(9).kind(), ErrorKind::NeedsHoming);
    for code in [0, 1, 2, 3, 15, 20, 22, 255] {
        assert_eq!(e(code).kind(), ErrorKind::Rejected, "error:{code}");
    }
    assert_eq!(HalError::NotHomed.kind(), ErrorKind::NeedsHoming);
    let lost = HalError::LostPosition {
        detail: "ALARM:1".into(),
    };
    assert_eq!(lost.kind(), ErrorKind::NeedsHoming);
    let gone = HalError::Disconnected {
        device: DeviceKind::Camera,
        detail: "USB reset".into(),
    };
    assert_eq!(gone.kind(), ErrorKind::Disconnected);
}

#[test]
fn malformed_pixel_buffers_are_typed_errors() {
    let data: Vec<u16> = (0..16).map(|i| (i * 60) as u16).collect();
    for format in [
        Bayer10Format::MipiPacked,
        Bayer10Format::Lsb16,
        Bayer10Format::Msb16,
    ] {
        let packed = pack_bayer10(format, &data, 4, 4).unwrap();
        // too short, a stride shorter than a row, an empty frame
        let short = unpack_bayer10(format, &packed[..packed.len() - 1], 4, 4, None).unwrap_err();
        assert_eq!(short.kind(), ErrorKind::InvalidData, "{format:?}: {short}");
        let stride = unpack_bayer10(format, &packed, 4, 4, Some(1)).unwrap_err();
        assert_eq!(
            stride.kind(),
            ErrorKind::InvalidData,
            "{format:?}: {stride}"
        );
        let empty = unpack_bayer10(format, &packed, 0, 4, None).unwrap_err();
        assert_eq!(empty.kind(), ErrorKind::InvalidData, "{format:?}: {empty}");
    }
    // A 16-bit sample with bits below the 10-bit value set is not what the camera sends.
    let msb = vec![0xffu8; 4 * 4 * 2];
    let e = unpack_bayer10(Bayer10Format::Msb16, &msb, 4, 4, None).unwrap_err();
    assert!(matches!(e, HalError::CorruptedFrame { .. }), "{e}");
    assert_eq!(e.kind(), ErrorKind::CorruptedFrame);
}

#[test]
fn frames_that_break_their_own_header_are_corrupted() {
    let frame = |w, h, depth, data: Vec<u16>, exposure| {
        BayerFrame::new(
            w,
            h,
            depth,
            BayerPattern::Rggb,
            data,
            exposure,
            0.0,
            25.0,
            0,
        )
    };
    for e in [
        frame(2, 2, 10, vec![1024, 0, 0, 0], 0.01).unwrap_err(),
        frame(2, 2, 10, vec![0; 3], 0.01).unwrap_err(),
        frame(2, 2, 0, vec![0; 4], 0.01).unwrap_err(),
        frame(2, 2, 10, vec![0; 4], f64::NAN).unwrap_err(),
        frame(2, 2, 10, vec![0; 4], 0.0).unwrap_err(),
        frame(0, 0, 10, vec![], 0.01).unwrap_err(),
    ] {
        assert_eq!(e.kind(), ErrorKind::CorruptedFrame, "{e}");
    }
}

#[test]
fn damaged_frame_files_are_refused() {
    let f = BayerFrame::new(
        2,
        2,
        10,
        BayerPattern::Rggb,
        vec![1, 2, 3, 4],
        0.01,
        0.0,
        25.0,
        0,
    )
    .unwrap();
    let bytes = encode_frames(&[f.clone(), f]);
    assert_eq!(decode_frames(&bytes).unwrap().len(), 2);
    assert!(decode_frames(&[]).is_err());
    for cut in [1, 8, bytes.len() / 2, bytes.len() - 1] {
        assert!(decode_frames(&bytes[..cut]).is_err(), "cut at {cut}");
    }
    let mut flipped = bytes.clone();
    let mid = flipped.len() / 2;
    flipped[mid] ^= 0x40;
    assert!(decode_frames(&flipped).is_err());
}

#[test]
fn malformed_rig_files_are_config_errors() {
    for text in ["backend = ", "backend = \"quantum\"", "[motion]\nport = 3"] {
        let e = RigConfig::from_toml_str(text)
            .and_then(|c| c.validate())
            .unwrap_err();
        assert_eq!(e.kind(), ErrorKind::Config, "{text}: {e}");
    }
}
