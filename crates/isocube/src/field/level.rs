//! Levels chosen from the data: Otsu's threshold of the value histogram, or a fraction of the
//! value range — and the range itself, which a user needs when a level meets no cell.

use rayon::prelude::*;

use super::PlaneSource;

/// The tie rule, one for every path: a value at or above the level counts as **above**. Every
/// extraction path — in place, converted slab by slab, streamed, boxes of cells, ternary
/// snapping, the volume mesher's inside test — classifies points through this function, so a
/// value exactly at the level (integer data, mostly) falls on the same side everywhere. (The
/// face and interior deciders compare exact offsets from the level, `v − level ≥ 0` in `f64`,
/// which is the same test: the difference of two `f32` values has the sign of the exact one.)
///
/// ```
/// use isocube::field::is_above;
/// assert!(is_above(0.0, 0.0) && is_above(1.0, 0.0) && !is_above(-1.0, 0.0));
/// assert!(!is_above(f32::NAN, 0.0));
/// ```
#[inline(always)]
pub fn is_above(value: f32, level: f32) -> bool {
    value >= level
}

/// The iso-value to extract at, as a user gives it: a number, `auto` (Otsu's threshold of the
/// values' histogram: the level that best splits them in two classes) or a fraction of the
/// value range (`40%`: min + 0.4 · (max − min)).
///
/// ```
/// use isocube::field::{Level, ValueSummary};
/// let level: Level = "25%".parse().unwrap();
/// let summary = ValueSummary::of(&[2.0, 4.0, 6.0, 10.0]).unwrap();
/// assert_eq!(level.resolve(&summary), 4.0);
/// assert_eq!("auto".parse::<Level>().unwrap(), Level::Otsu);
/// assert_eq!("-1.5".parse::<Level>().unwrap(), Level::Value(-1.5));
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Level {
    /// This value.
    Value(f32),
    /// Otsu's threshold of the values' histogram (256 bins over their range).
    Otsu,
    /// `min + f · (max − min)` of the finite values, `f` in `[0, 1]`.
    Fraction(f32),
}

impl Default for Level {
    fn default() -> Self {
        Level::Value(0.0)
    }
}

impl std::str::FromStr for Level {
    type Err = crate::ParseError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let bad = |why: String| crate::ParseError::new("level", s, why);
        let t = s.trim();
        if t.eq_ignore_ascii_case("auto") || t.eq_ignore_ascii_case("otsu") {
            return Ok(Level::Otsu);
        }
        if let Some(p) = t.strip_suffix('%') {
            return match p.trim().parse::<f32>() {
                Ok(f) if (0.0..=100.0).contains(&f) => Ok(Level::Fraction(f / 100.0)),
                _ => Err(bad(format!(
                    "level '{s}': a percentage of the value range is from 0% to 100%"
                ))),
            };
        }
        match t.parse::<f32>() {
            Ok(v) if v.is_finite() => Ok(Level::Value(v)),
            _ => Err(bad(format!(
                "level '{s}': expected a number, `auto` (Otsu's threshold) or a percentage of \
                 the value range such as `40%`"
            ))),
        }
    }
}

impl std::fmt::Display for Level {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Level::Value(v) => write!(f, "{v}"),
            Level::Otsu => f.write_str("auto"),
            Level::Fraction(x) => write!(f, "{}%", x * 100.0),
        }
    }
}

impl Level {
    /// Whether the level depends on the data (it needs a [`ValueSummary`]).
    pub fn from_data(&self) -> bool {
        !matches!(self, Level::Value(_))
    }

    /// The number, from the values' summary.
    pub fn resolve(&self, summary: &ValueSummary) -> f32 {
        match *self {
            Level::Value(v) => v,
            Level::Fraction(f) => {
                let (lo, hi) = (f64::from(summary.min), f64::from(summary.max));
                (lo + f64::from(f) * (hi - lo)) as f32
            }
            Level::Otsu => summary.otsu(),
        }
    }
}

/// Bins of [`ValueSummary`]'s histogram.
const BINS: usize = 256;

/// The finite values of a volume: their range and a histogram of 256 bins over it.
#[derive(Clone, Debug, PartialEq)]
pub struct ValueSummary {
    /// The smallest finite value.
    pub min: f32,
    /// The largest finite value.
    pub max: f32,
    /// Finite values counted.
    pub count: u64,
    histogram: Vec<u64>,
}

impl ValueSummary {
    /// The summary of `values`, or `None` when none is finite.
    pub fn of(values: &[f32]) -> Option<ValueSummary> {
        let (min, max) = values
            .par_chunks(1 << 16)
            .map(range_of)
            .reduce(|| None, merge_ranges)?;
        let histogram = values
            .par_chunks(1 << 16)
            .map(|c| histogram_of(c, min, max))
            .reduce(|| vec![0; BINS], add_histograms);
        Some(ValueSummary {
            min,
            max,
            count: histogram.iter().sum(),
            histogram,
        })
    }

    /// The summary of a volume read plane by plane (twice: the range, then the histogram), or
    /// `None` when no value is finite.
    pub fn of_source(source: &impl PlaneSource) -> Option<ValueSummary> {
        let (min, max) = fold_planes(source, None, |acc, v| merge_ranges(acc, range_of(v)))?;
        let histogram = fold_planes(source, vec![0; BINS], |acc, v| {
            add_histograms(acc, histogram_of(v, min, max))
        });
        Some(ValueSummary {
            min,
            max,
            count: histogram.iter().sum(),
            histogram,
        })
    }

    /// Otsu's threshold: the bin edge that maximises the variance between the values below
    /// and above it. Empty bins between two classes leave that variance unchanged; of the
    /// edges that tie, the middle one is taken, so two well-separated classes are split half
    /// way. A constant volume gives its value.
    pub fn otsu(&self) -> f32 {
        let total = self.count as f64;
        let all: f64 = self
            .histogram
            .iter()
            .enumerate()
            .map(|(k, &h)| k as f64 * h as f64)
            .sum();
        let (mut below, mut sum_below) = (0.0f64, 0.0f64);
        // (variance, first and last bin of the tie).
        let mut best = (f64::NEG_INFINITY, 0usize, 0usize);
        for (k, &h) in self.histogram.iter().enumerate() {
            below += h as f64;
            sum_below += k as f64 * h as f64;
            let above = total - below;
            if below == 0.0 {
                continue;
            }
            if above == 0.0 {
                break;
            }
            let gap = sum_below / below - (all - sum_below) / above;
            let between = below * above * gap * gap;
            if between > best.0 {
                best = (between, k, k);
            } else if between == best.0 && h == 0 {
                best.2 = k;
            }
        }
        if best.0 == f64::NEG_INFINITY {
            return self.min;
        }
        let width = (f64::from(self.max) - f64::from(self.min)) / BINS as f64;
        let edge = |k: usize| f64::from(self.min) + (k + 1) as f64 * width;
        ((edge(best.1) + edge(best.2)) / 2.0) as f32
    }
}

fn range_of(values: &[f32]) -> Option<(f32, f32)> {
    values
        .iter()
        .filter(|v| v.is_finite())
        .fold(None, |acc, &v| merge_ranges(acc, Some((v, v))))
}

fn merge_ranges(a: Option<(f32, f32)>, b: Option<(f32, f32)>) -> Option<(f32, f32)> {
    match (a, b) {
        (Some(a), Some(b)) => Some((a.0.min(b.0), a.1.max(b.1))),
        (a, None) => a,
        (None, b) => b,
    }
}

fn histogram_of(values: &[f32], min: f32, max: f32) -> Vec<u64> {
    let mut h = vec![0u64; BINS];
    let width = f64::from(max) - f64::from(min);
    for &v in values.iter().filter(|v| v.is_finite()) {
        let k = if width > 0.0 {
            ((f64::from(v) - f64::from(min)) / width * BINS as f64) as usize
        } else {
            0
        };
        h[k.min(BINS - 1)] += 1;
    }
    h
}

fn add_histograms(mut a: Vec<u64>, b: Vec<u64>) -> Vec<u64> {
    for (x, y) in a.iter_mut().zip(b) {
        *x += y;
    }
    a
}

/// Folds `f` over a source's values, a batch of planes at a time.
fn fold_planes<T>(source: &impl PlaneSource, init: T, mut f: impl FnMut(T, &[f32]) -> T) -> T {
    let [nx, ny, nz] = source.dims();
    let plane = nx * ny;
    let batch = (1 << 22) / plane.max(1);
    let batch = batch.clamp(1, nz.max(1));
    let mut buffer = vec![0.0f32; plane * batch];
    let mut acc = init;
    let mut z = 0;
    while z < nz {
        let n = batch.min(nz - z);
        let out = &mut buffer[..plane * n];
        source.read_planes(z, out);
        acc = f(acc, out);
        z += n;
    }
    acc
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::Grid;

    /// Two well-separated classes: Otsu's threshold falls between them; the same summary
    /// from the values and from the volume read plane by plane.
    #[test]
    fn otsu_splits_two_classes_and_sources_agree() {
        let values: Vec<f32> = (0..4096)
            .map(|n| {
                if n % 3 == 0 {
                    200.0 + (n % 7) as f32
                } else {
                    20.0 + (n % 5) as f32
                }
            })
            .collect();
        let grid = Grid::new([16, 16, 16], values.clone()).unwrap();
        let a = ValueSummary::of(&values).unwrap();
        let b = ValueSummary::of_source(&grid).unwrap();
        assert_eq!(a, b);
        assert_eq!((a.min, a.max, a.count), (20.0, 206.0, 4096));
        let t = a.otsu();
        assert!(t > 24.0 && t <= 200.0, "{t}");
        assert_eq!(Level::Otsu.resolve(&a), t);
        assert_eq!(Level::Fraction(0.5).resolve(&a), 113.0);
        // NaN is left out; nothing finite is no summary; a constant volume gives its value.
        assert_eq!(ValueSummary::of(&[f32::NAN, 1.0, 3.0]).unwrap().count, 2);
        assert!(ValueSummary::of(&[f32::NAN, f32::INFINITY]).is_none());
        assert_eq!(ValueSummary::of(&[5.0; 10]).unwrap().otsu(), 5.0);
    }

    #[test]
    fn levels_parse_and_refuse() {
        assert_eq!("40%".parse::<Level>().unwrap(), Level::Fraction(0.4));
        assert_eq!(" Auto ".parse::<Level>().unwrap(), Level::Otsu);
        assert_eq!("1e3".parse::<Level>().unwrap(), Level::Value(1000.0));
        for bad in ["150%", "x", "nan", "inf", "-5%"] {
            let e = bad.parse::<Level>().unwrap_err().to_string();
            assert!(e.contains("level"), "{bad}: {e}");
        }
        assert_eq!(Level::Fraction(0.4).to_string(), "40%");
    }
}
