//! Output formatted in blocks on all cores and written in order: the bytes are exactly those of
//! formatting the records one after another, so every writer keeps its format while large
//! meshes are written at the speed of the disk rather than of one core's formatting.

use std::io::{self, Write};
use std::ops::Range;

use rayon::prelude::*;

/// Records per block: large enough that a block's formatting outweighs scheduling it, small
/// enough that a batch of blocks (two per thread) stays a few MiB.
const BLOCK: usize = 1 << 14;

/// Formats records `0..count` with `format` (called on consecutive ranges, appending their
/// bytes to the buffer it is given) and writes the bytes to `w` in record order.
///
/// ```ignore
/// write_blocks(w, positions.len(), |out, range| {
///     for p in &positions[range] {
///         writeln!(out, "{} {} {}", p[0], p[1], p[2]).unwrap();
///     }
/// })?;
/// ```
pub(crate) fn write_blocks<W: Write + ?Sized>(
    w: &mut W,
    count: usize,
    format: impl Fn(&mut Vec<u8>, Range<usize>) + Sync,
) -> io::Result<()> {
    if count <= BLOCK {
        let mut out = Vec::new();
        format(&mut out, 0..count);
        return w.write_all(&out);
    }
    let per_batch = 2 * rayon::current_num_threads().max(1);
    let mut buffers: Vec<Vec<u8>> = vec![Vec::new(); per_batch];
    let blocks = count.div_ceil(BLOCK);
    for first in (0..blocks).step_by(per_batch) {
        let n = per_batch.min(blocks - first);
        buffers[..n]
            .par_iter_mut()
            .enumerate()
            .for_each(|(i, out)| {
                out.clear();
                let start = (first + i) * BLOCK;
                format(out, start..(start + BLOCK).min(count));
            });
        for out in &buffers[..n] {
            w.write_all(out)?;
        }
    }
    Ok(())
}

/// Appends the integers in decimal separated by `sep`, then a newline (`itoa`: large ASCII
/// meshes are mostly such lines, and `write!` spends most of its time on its machinery).
pub(crate) fn put_ints(out: &mut Vec<u8>, xs: &[usize], sep: &[u8]) {
    let mut digits = itoa::Buffer::new();
    for (i, &x) in xs.iter().enumerate() {
        if i > 0 {
            out.extend_from_slice(sep);
        }
        out.extend_from_slice(digits.format(x).as_bytes());
    }
    out.push(b'\n');
}

/// Appends `x` in decimal.
pub(crate) fn put_int(out: &mut Vec<u8>, x: usize) {
    out.extend_from_slice(itoa::Buffer::new().format(x).as_bytes());
}

/// Appends `x` in its shortest form that reads back as the same `f32` (`zmij`; `1.0`, `2.5e-8`).
pub(crate) fn put_float(out: &mut Vec<u8>, x: f32) {
    out.extend_from_slice(zmij::Buffer::new().format(x).as_bytes());
}

/// Appends `xs` as little-endian bytes.
pub(crate) fn put_le(out: &mut Vec<u8>, xs: &[f32]) {
    for x in xs {
        out.extend_from_slice(&x.to_le_bytes());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integer_lines_read_back() {
        let xs = [0, 9, 10, 99, 100, 4_294_967_295, usize::MAX, 123_456_789];
        let mut out = Vec::new();
        put_ints(&mut out, &xs, b", ");
        let expected: Vec<String> = xs.iter().map(|x| x.to_string()).collect();
        assert_eq!(String::from_utf8(out).unwrap(), expected.join(", ") + "\n");
    }

    #[test]
    fn blocks_write_the_bytes_of_one_pass_in_order() {
        for count in [
            0,
            1,
            BLOCK - 1,
            BLOCK,
            BLOCK + 1,
            7 * BLOCK + 3,
            40 * BLOCK + 5,
        ] {
            let line = |out: &mut Vec<u8>, i: usize| writeln!(out, "{i} {}", i * i).unwrap();
            let mut serial = Vec::new();
            (0..count).for_each(|i| line(&mut serial, i));
            let mut blocked = Vec::new();
            write_blocks(&mut blocked, count, |out, r| r.for_each(|i| line(out, i))).unwrap();
            assert_eq!(blocked, serial, "{count} records");
        }
    }
}
