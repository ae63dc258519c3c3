//! Decoding any byte string returns a message or an error, never panics; and whatever decodes
//! re-encodes to bytes that decode to the same encoding (floats may be NaN, so compare bytes).

use proptest::prelude::*;
use voxcube_kernel::node::msg::{Msg, MsgKind, MAX_MSG_LEN};

fn reencode(m: &Msg) -> Vec<u8> {
    let mut buf = [0u8; MAX_MSG_LEN];
    let n = m.encode(&mut buf);
    buf[..n].to_vec()
}

const KINDS: [MsgKind; 8] = [
    MsgKind::Ray,
    MsgKind::Hit,
    MsgKind::Resolved,
    MsgKind::Ack,
    MsgKind::Token,
    MsgKind::Pixels,
    MsgKind::Stats,
    MsgKind::Planes,
];

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn arbitrary_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..400)) {
        if let Ok(m) = Msg::decode(&bytes) {
            let once = reencode(&m);
            let twice = reencode(&Msg::decode(&once).expect("an encoding decodes"));
            prop_assert_eq!(once, twice);
        }
    }

    /// Bytes of the right length for a kind reach the field checks, not just the length check.
    #[test]
    fn well_sized_random_messages_decode_or_name_a_field(kind in 0usize..8, body in prop::collection::vec(any::<u8>(), MAX_MSG_LEN)) {
        let kind = KINDS[kind];
        let mut bytes = body[..kind.encoded_len()].to_vec();
        bytes[0] = kind as u8;
        match Msg::decode(&bytes) {
            Ok(m) => prop_assert_eq!(m.kind(), kind),
            Err(e) => prop_assert!(e.to_string().contains("field"), "{}", e),
        }
    }
}
