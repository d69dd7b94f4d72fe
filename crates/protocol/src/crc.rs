//! CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, no final XOR), written for the frame protocol.

/// The CRC generator polynomial x^16 + x^12 + x^5 + 1, MSB-first.
pub const CRC16_POLY: u16 = 0x1021;
/// The register's initial value.
pub const CRC16_INIT: u16 = 0xFFFF;

/// A 256-entry table built at compile time: one shift-and-xor per byte instead of eight.
const TABLE: [u16; 256] = build_table();

const fn build_table() -> [u16; 256] {
    let mut table = [0u16; 256];
    let mut i = 0;
    while i < 256 {
        let mut crc = (i as u16) << 8;
        let mut bit = 0;
        while bit < 8 {
            crc = if crc & 0x8000 != 0 {
                (crc << 1) ^ CRC16_POLY
            } else {
                crc << 1
            };
            bit += 1;
        }
        table[i] = crc;
        i += 1;
    }
    table
}

/// Continues a CRC over more bytes (start with `CRC16_INIT`).
pub fn crc16_update(mut crc: u16, data: &[u8]) -> u16 {
    for &b in data {
        let idx = ((crc >> 8) as u8 ^ b) as usize;
        crc = (crc << 8) ^ TABLE[idx];
    }
    crc
}

/// CRC-16/CCITT-FALSE of `data`.
pub fn crc16(data: &[u8]) -> u16 {
    crc16_update(CRC16_INIT, data)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bit-by-bit reference, a different method from the table.
    fn crc16_bitwise(data: &[u8]) -> u16 {
        let mut crc = CRC16_INIT;
        for &b in data {
            for i in (0..8).rev() {
                let inbit = (b >> i) & 1 == 1;
                let top = crc & 0x8000 != 0;
                crc <<= 1;
                if inbit != top {
                    crc ^= CRC16_POLY;
                }
            }
        }
        crc
    }

    #[test]
    fn catalogue_check_value() {
        // The CRC catalogue's check value for CRC-16/CCITT-FALSE (a.k.a. CRC-16/IBM-3740).
        assert_eq!(crc16(b"123456789"), 0x29B1);
        assert_eq!(crc16(b""), 0xFFFF);
    }

    #[test]
    fn table_matches_bitwise() {
        let data: Vec<u8> = (0..=255u8)
            .chain((0..100).map(|i| (i * 37 % 251) as u8))
            .collect();
        for n in 0..data.len() {
            assert_eq!(crc16(&data[..n]), crc16_bitwise(&data[..n]));
        }
    }

    #[test]
    fn protocol_doc_example() {
        // The worked example in docs/protocol.md: a heartbeat, seq 7, counter 1.
        let body = [0x04, 0x07, 0x03, 0x01, 0x00, 0x00, 0x00];
        assert_eq!(crc16(&body), 0x602F);
    }
}
