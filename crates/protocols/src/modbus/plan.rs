//! Read planning: neighbouring registers of a unit grouped into as few requests as possible, and
//! split again per channel when a module refuses a grouped read.

use super::codec::{Encoding, RegisterKind, WordOrder, MAX_READ_REGISTERS};

/// Neighbouring registers of one unit and table, read in one request.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ReadBlock {
    /// Unit identifier.
    pub unit: u8,
    /// Register table.
    pub kind: RegisterKind,
    /// First protocol address.
    pub address: u16,
    /// Number of registers (≤ 125).
    pub count: u16,
    /// The channels it serves: (channel index, offset of its first register in the block).
    pub members: Vec<(usize, u16)>,
}

/// The largest gap of unused registers that is still read through rather than split into two
/// requests.
pub const MAX_GAP_REGISTERS: u16 = 16;

/// A channel's place: (unit, table, protocol address, registers).
pub type RegisterSpan = (u8, RegisterKind, u16, u16);

/// Groups channels into as few reads as possible: same unit and table, at most 125 registers,
/// gaps of at most [`MAX_GAP_REGISTERS`]. Spans must lie within 0–65535.
pub fn plan_reads(spans: &[RegisterSpan]) -> Vec<ReadBlock> {
    let mut order: Vec<usize> = (0..spans.len()).collect();
    order.sort_by_key(|&i| (spans[i].0, spans[i].1, spans[i].2, i));
    let mut blocks: Vec<ReadBlock> = Vec::new();
    for i in order {
        let (unit, kind, address, n) = spans[i];
        let end = u32::from(address) + u32::from(n);
        if let Some(b) = blocks.last_mut() {
            let b_end = u32::from(b.address) + u32::from(b.count);
            if b.unit == unit
                && b.kind == kind
                && u32::from(address) <= b_end + u32::from(MAX_GAP_REGISTERS)
                && end.max(b_end) - u32::from(b.address) <= u32::from(MAX_READ_REGISTERS)
            {
                b.count = (end.max(b_end) - u32::from(b.address)) as u16;
                b.members.push((i, address - b.address));
                continue;
            }
        }
        blocks.push(ReadBlock {
            unit,
            kind,
            address,
            count: n,
            members: vec![(i, 0)],
        });
    }
    blocks
}

/// Replaces the blocks at `indices` by one block per channel (its own registers only).
pub fn split_blocks(
    blocks: &[ReadBlock],
    indices: &[usize],
    decoders: &[(Encoding, WordOrder)],
) -> Vec<ReadBlock> {
    let mut out = Vec::with_capacity(blocks.len());
    for (b, block) in blocks.iter().enumerate() {
        if !indices.contains(&b) {
            out.push(block.clone());
            continue;
        }
        for &(k, offset) in &block.members {
            let count = decoders.get(k).map_or(1, |(e, _)| e.registers());
            out.push(ReadBlock {
                unit: block.unit,
                kind: block.kind,
                address: block.address.saturating_add(offset),
                count,
                members: vec![(k, 0)],
            });
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_are_grouped() {
        use RegisterKind::*;
        let spans = [
            (1, Holding, 10, 1),
            (1, Holding, 0, 2),
            (1, Input, 0, 1),
            (2, Holding, 0, 1),
            (1, Holding, 11, 2),
            (1, Holding, 200, 1),
        ];
        let blocks = plan_reads(&spans);
        assert_eq!(blocks.len(), 4);
        assert_eq!(
            blocks[0],
            ReadBlock {
                unit: 1,
                kind: Holding,
                address: 0,
                count: 13,
                members: vec![(1, 0), (0, 10), (4, 11)]
            }
        );
        assert_eq!(
            blocks[1],
            ReadBlock {
                unit: 1,
                kind: Holding,
                address: 200,
                count: 1,
                members: vec![(5, 0)]
            }
        );
        assert_eq!(blocks[2].kind, Input);
        assert_eq!(blocks[3].unit, 2);
        // 125 registers at most per read.
        let spans: Vec<RegisterSpan> = (0..130).map(|a| (1, Holding, a, 1)).collect();
        let blocks = plan_reads(&spans);
        assert_eq!(
            (blocks[0].count, blocks[1].address, blocks[1].count),
            (125, 125, 5)
        );
    }

    #[test]
    fn refused_blocks_are_split_per_channel() {
        use RegisterKind::*;
        let spans = [(1, Input, 0, 1), (1, Input, 10, 2), (1, Holding, 0, 1)];
        let decoders = [
            (Encoding::Int16Tenths, WordOrder::HighFirst),
            (Encoding::Float32, WordOrder::LowFirst),
            (Encoding::Uint16, WordOrder::HighFirst),
        ];
        let blocks = plan_reads(&spans);
        assert_eq!(blocks.len(), 2); // holding 0; input 0–11
        let split = split_blocks(&blocks, &[1], &decoders);
        assert_eq!(split.len(), 3);
        assert_eq!(split[0], blocks[0]);
        assert_eq!(
            split[1],
            ReadBlock {
                unit: 1,
                kind: Input,
                address: 0,
                count: 1,
                members: vec![(0, 0)]
            }
        );
        assert_eq!(
            split[2],
            ReadBlock {
                unit: 1,
                kind: Input,
                address: 10,
                count: 2,
                members: vec![(1, 0)]
            }
        );
    }
}
