//! The pickle reader on a fixture made by numpy (tests/fixtures/make_pickle.py).

use std::path::Path;

use mhi_net::pickle::read_weights_pickle;

const TINY: &[u8] = include_bytes!("fixtures/tiny.pkl");

#[test]
fn reads_nested_float32_arrays() {
    let w = read_weights_pickle(TINY, Path::new("tiny.pkl")).unwrap();
    assert_eq!(w.len(), 3);
    let k = &w["Net_0/Conv_0/kernel"];
    assert_eq!(k.shape, vec![2, 3, 1, 4]);
    let expected: Vec<f32> = (0..24).map(|v| v as f32 / 8.0).collect();
    assert_eq!(k.data, expected);
    assert_eq!(w["Net_0/Conv_0/bias"].data, vec![1.5, -2.25, 3.0, 0.0]);
    assert_eq!(w["Lin_0/Conv_0/kernel"].shape, vec![1, 1, 4, 1]);
}

#[test]
fn truncated_or_corrupt_pickles_are_errors_with_offsets() {
    for cut in [0, 1, 10, TINY.len() / 2, TINY.len() - 1] {
        let e = read_weights_pickle(&TINY[..cut], Path::new("tiny.pkl")).unwrap_err();
        assert!(e.to_string().starts_with("tiny.pkl: byte "), "{e}");
    }
    // Arbitrary byte flips never panic.
    let mut state = 0x1234_5678_u64;
    for _ in 0..5000 {
        let mut b = TINY.to_vec();
        for _ in 0..4 {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let i = (state >> 33) as usize % b.len();
            b[i] = (state >> 17) as u8;
        }
        let _ = read_weights_pickle(&b, Path::new("x"));
    }
}

/// A pickle that nests lists a hundred thousand deep (`]` EMPTY_LIST, then `a` APPEND of the
/// next into the one before, in a way Python writes as `[[[[…]]]]`): refused with the depth,
/// not a stack overflow when it is dropped.
#[test]
fn a_deeply_nested_pickle_is_refused() {
    let depth = 100_000;
    let mut b = vec![0x80, 2];
    for _ in 0..depth {
        b.push(b'('); // MARK
        b.push(b']'); // EMPTY_LIST
    }
    // APPENDS: the list on top goes into the one below.
    b.extend(std::iter::repeat_n(b'e', depth));
    b.push(b'.');
    let e = read_weights_pickle(&b, Path::new("deep.ckpt"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("nests deeper than"), "{e}");
}

/// A 1.3 kB "memo bomb": a tuple of the memoised value twice, memoised again, 60 times over,
/// would be 2^60 objects. Refused after a bounded amount of work.
#[test]
fn a_memo_bomb_is_refused() {
    let mut b = vec![0x80, 2, b'N', b'q', 0]; // None, BINPUT 0
    for i in 0..60u8 {
        // BINGET i, BINGET i, TUPLE2, BINPUT i+1
        b.extend([b'h', i, b'h', i, 0x86, b'q', i + 1]);
    }
    b.push(b'.');
    assert!(b.len() < 1400);
    let e = read_weights_pickle(&b, Path::new("bomb.ckpt"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("memo bomb"), "{e}");
}
