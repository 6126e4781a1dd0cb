//! Axes: the range an axis covers, its ticks and their labels, and the
//! coordinate type that hands both to plotters.
//!
//! The ticks are chosen here, not by plotters: an axis of iterations gets
//! whole numbers only (no 2.5 iterations), a log axis at least two labelled
//! ticks whatever its span (plotters labels only the powers of ten inside it,
//! one or none on a range narrower than a decade), and every tick is labelled.

use plotters::coord::ranged1d::{KeyPointHint, NoDefaultFormatting, Ranged, ValueFormatter};
use std::ops::Range;

/// How an axis maps values to positions.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Scale {
    #[default]
    Linear,
    /// Logarithmic; non-positive values cannot be shown.
    Log,
    /// Linear with ticks at whole numbers only (iterations, counts).
    Integer,
}

impl Scale {
    pub fn is_log(self) -> bool {
        self == Scale::Log
    }
}

/// Largest magnitude drawn. plotters' tick generation never returns when an
/// axis' width (or, on a log axis, its ratio) overflows to infinity, and
/// values this large are not results anyone plots, so they are skipped like
/// non-finite ones.
pub const MAX_SHOWN: f64 = 1e300;

/// Most decades a log axis spans (its ratio must stay finite, see
/// [`MAX_SHOWN`]); when the data span more, the lowest are cut off.
const MAX_DECADES: f64 = 200.0;

/// Smallest axis width relative to the values' magnitude. Narrower ranges make
/// tick rounding work at the limit of f64 precision; data that vary less
/// than this are drawn as flat.
pub const MIN_REL_WIDTH: f64 = 1e-6;

/// Whether a coordinate can be placed on its axis.
pub fn shown(v: f64, log: bool) -> bool {
    v.is_finite() && v.abs() <= MAX_SHOWN && (!log || v >= 1.0 / MAX_SHOWN)
}

/// The axis range covering `values` with a little room, never empty or
/// degenerate (the mapping divides by its width), positive on a log axis, and
/// within the limits above.
pub fn axis_range(values: impl Iterator<Item = f64>, log: bool) -> Range<f64> {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    });
    if !(lo.is_finite() && hi.is_finite()) {
        return if log { 1.0..10.0 } else { 0.0..1.0 };
    }
    if log {
        // Padding by a constant factor is a constant distance on the log axis.
        let lo = lo.max(hi / 10f64.powf(MAX_DECADES));
        if hi / lo < 1.0 + MIN_REL_WIDTH {
            (lo / 2.0)..(hi * 2.0)
        } else {
            (lo / 1.1)..(hi * 1.1)
        }
    } else {
        let mag = lo.abs().max(hi.abs());
        let width = hi - lo;
        let pad = if width > MIN_REL_WIDTH * mag {
            0.05 * width
        } else if mag > 0.0 {
            0.5 * mag
        } else {
            0.5
        };
        (lo - pad)..(hi + pad)
    }
}

/// `range` where it can be an axis (finite, increasing, not narrower than
/// [`MIN_REL_WIDTH`], positive on a log axis), else None.
pub fn valid_range(range: (f64, f64), log: bool) -> Option<Range<f64>> {
    let (lo, hi) = range;
    let ok = shown(lo, log)
        && shown(hi, log)
        && hi > lo
        && hi - lo > MIN_REL_WIDTH * lo.abs().max(hi.abs());
    ok.then_some(lo..hi)
}

/// Multiples of a step of 1, 2 or 5 times a power of ten (and at least
/// `min_step`) from `lo` to `hi`: the finest such step that gives at most `max`
/// ticks. Each tick is the multiple written exactly (0.6, not 0.6000000000000001).
pub fn linear_ticks(lo: f64, hi: f64, max: usize, min_step: f64) -> Vec<f64> {
    if !(lo.is_finite() && hi.is_finite() && hi >= lo) {
        return Vec::new();
    }
    let max = max.max(2) as f64;
    let span = hi - lo;
    if span == 0.0 {
        return vec![lo];
    }
    let mut power = (span / max).log10().floor() as i32;
    loop {
        for m in [1.0, 2.0, 5.0] {
            let step = m * 10f64.powi(power);
            if step < min_step {
                continue;
            }
            let (first, last) = ((lo / step).ceil(), (hi / step).floor());
            if last - first < max {
                return (0..=(last - first) as i64)
                    .map(|i| times_pow10((first + i as f64) * m, power) + 0.0)
                    .collect();
            }
        }
        power += 1;
    }
}

/// `m * 10^e`, correctly rounded where `m` and `10^|e|` are exact (0.6 for
/// `6e-1`, where `6.0 * 10f64.powi(-1)` is 0.6000000000000001).
fn times_pow10(m: f64, e: i32) -> f64 {
    if e >= 0 {
        m * 10f64.powi(e)
    } else {
        m / 10f64.powi(-e)
    }
}

/// Ticks of a log axis from `lo` to `hi` (both positive), at most `max`:
/// the powers of ten where there are three or more (every second, fifth ...
/// where they are too many); else 1, 2 and 5 times them; else (less than
/// about half a decade) evenly spaced round numbers, so that every log axis
/// has at least two labelled ticks.
pub fn log_ticks(lo: f64, hi: f64, max: usize) -> Vec<f64> {
    if !(lo > 0.0 && hi >= lo && hi.is_finite()) {
        return Vec::new();
    }
    let max = max.max(2);
    let (first, last) = (lo.log10().ceil() as i32, hi.log10().floor() as i32);
    let decade = |e: i32| times_pow10(1.0, e);
    let powers = (first..=last).filter(|&e| (lo..=hi).contains(&decade(e)));
    let count = powers.clone().count();
    if count >= 3 {
        let stride = count.div_ceil(max) as i32;
        return powers
            .filter(|e| e.rem_euclid(stride) == 0)
            .map(decade)
            .collect();
    }
    let mut ticks: Vec<f64> = (first - 1..=last)
        .flat_map(|e| [1.0, 2.0, 5.0].map(|m| times_pow10(m, e)))
        .filter(|v| (lo..=hi).contains(v))
        .collect();
    if ticks.len() < 3 || ticks.len() > max {
        let even = linear_ticks(lo, hi, max.min(6), 0.0);
        if even.len() >= ticks.len() || ticks.len() > max {
            ticks = even;
        }
    }
    ticks
}

/// The ticks of an axis of `scale` over `range`, at most `max`.
pub fn ticks(range: &Range<f64>, scale: Scale, max: usize) -> Vec<f64> {
    match scale {
        Scale::Linear => linear_ticks(range.start, range.end, max, 0.0),
        Scale::Integer => linear_ticks(range.start, range.end, max, 1.0),
        Scale::Log => log_ticks(range.start, range.end, max),
    }
}

/// Short tick text: plain for moderate magnitudes, exponent form otherwise,
/// with four significant digits (enough to tell ticks apart, short enough to
/// fit).
pub fn tick_label(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 {
        "0".to_string()
    } else if (1e-3..1e5).contains(&a) {
        let digits = (3 - a.log10().floor() as i32).clamp(0, 6) as usize;
        let s = format!("{v:.digits$}");
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    } else {
        let s = format!("{v:.3e}");
        match s.split_once('e') {
            Some((m, e)) if m.contains('.') => {
                format!("{}e{e}", m.trim_end_matches('0').trim_end_matches('.'))
            }
            _ => s,
        }
    }
}

/// An axis as plotters sees it: its range, linear or logarithmic, and the
/// ticks chosen above (plotters draws and labels exactly these).
#[derive(Debug, Clone)]
pub struct Coord {
    range: Range<f64>,
    log: bool,
    ticks: Vec<f64>,
}

impl Coord {
    /// An axis over `range` (valid for `scale`: see [`valid_range`]) with at
    /// most `max_ticks` ticks.
    pub fn new(range: Range<f64>, scale: Scale, max_ticks: usize) -> Coord {
        let ticks = ticks(&range, scale, max_ticks);
        Coord {
            range,
            log: scale.is_log(),
            ticks,
        }
    }

    pub fn ticks(&self) -> &[f64] {
        &self.ticks
    }

    pub fn range(&self) -> Range<f64> {
        self.range.clone()
    }

    /// Where `v` lies from the start (0) to the end (1) of the axis.
    fn fraction(&self, v: f64) -> f64 {
        let Range { start, end } = self.range;
        if self.log {
            (v.ln() - start.ln()) / (end.ln() - start.ln())
        } else {
            // Halved so that a range of +-1e300 does not overflow.
            (0.5 * v - 0.5 * start) / (0.5 * end - 0.5 * start)
        }
    }

    /// The pixel of `v` between the pixels `limit` of the axis' ends, not
    /// rounded (curves keep their sub-pixel shape).
    pub fn pixel(&self, v: f64, limit: (i32, i32)) -> f64 {
        let (a, b) = (f64::from(limit.0), f64::from(limit.1));
        a + (b - a) * self.fraction(v)
    }
}

impl Ranged for Coord {
    type FormatOption = NoDefaultFormatting;
    type ValueType = f64;

    fn map(&self, v: &f64, limit: (i32, i32)) -> i32 {
        let p = self.pixel(*v, limit);
        if p.is_nan() {
            limit.0
        } else {
            p.round().clamp(-1e7, 1e7) as i32
        }
    }

    /// The ticks for the labelled (bold) points, none for the light mesh.
    fn key_points<Hint: KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        if hint.weight().allow_light_points() {
            Vec::new()
        } else {
            self.ticks.clone()
        }
    }

    fn range(&self) -> Range<f64> {
        self.range.clone()
    }
}

impl ValueFormatter<f64> for Coord {
    fn format(v: &f64) -> String {
        tick_label(*v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linear_ticks_are_round_multiples() {
        assert_eq!(
            linear_ticks(0.0, 1.0, 6, 0.0),
            [0.0, 0.2, 0.4, 0.6, 0.8, 1.0]
        );
        assert_eq!(
            linear_ticks(-0.15, 3.15, 8, 0.0),
            [0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0]
        );
        assert_eq!(linear_ticks(0.03, 0.91, 5, 0.0), [0.2, 0.4, 0.6, 0.8]);
        assert_eq!(
            linear_ticks(-1.2e9, 1.9e9, 8, 0.0),
            [-1e9, -5e8, 0.0, 5e8, 1e9, 1.5e9]
        );
        assert_eq!(linear_ticks(2.0, 2.0, 8, 0.0), [2.0]);
        assert!(linear_ticks(f64::NAN, 1.0, 8, 0.0).is_empty());
        // Far from zero, narrow: still exact and increasing.
        let t = linear_ticks(1e15, 1e15 + 2.0, 8, 0.0);
        assert!(t.len() >= 2 && t.windows(2).all(|w| w[0] < w[1]), "{t:?}");
    }

    #[test]
    fn iteration_axes_tick_whole_numbers() {
        // 0 .. 3 iterations, padded: no 0.5 steps.
        assert_eq!(linear_ticks(-0.15, 3.15, 8, 1.0), [0.0, 1.0, 2.0, 3.0]);
        // A single iteration.
        assert_eq!(ticks(&(-0.5..0.5), Scale::Integer, 8), [0.0]);
        // Many: steps of 1, 2, 5, 10 ...
        assert_eq!(
            ticks(&(-2.0..42.0), Scale::Integer, 8),
            [0.0, 10.0, 20.0, 30.0, 40.0]
        );
        for (lo, hi) in [(-0.3, 7.3), (0.0, 1.0), (3.9, 4.1), (-10.0, 250.0)] {
            let t = ticks(&(lo..hi), Scale::Integer, 8);
            assert!(t.iter().all(|v| v.fract() == 0.0), "{lo} {hi}: {t:?}");
            assert!(t.len() <= 8, "{t:?}");
        }
    }

    #[test]
    fn log_axes_get_more_than_one_tick() {
        // Several decades: the powers of ten only.
        assert_eq!(log_ticks(3e-9, 0.7, 4), [1e-8, 1e-6, 1e-4, 1e-2]);
        assert_eq!(log_ticks(3e-9, 0.7, 8).len(), 8);
        assert_eq!(log_ticks(0.9e-3, 1.1, 8), [1e-3, 1e-2, 1e-1, 1.0]);
        // One or two decades: 1, 2 and 5 times them.
        assert_eq!(log_ticks(0.15, 1.2, 8), [0.2, 0.5, 1.0]);
        assert_eq!(log_ticks(0.9, 25.0, 8), [1.0, 2.0, 5.0, 10.0, 20.0]);
        // Within a decade, no power of ten: round numbers between.
        let t = log_ticks(0.31, 0.93, 8);
        assert_eq!(t, [0.4, 0.5, 0.6, 0.7, 0.8, 0.9]);
        let t = log_ticks(1.2e-6, 1.9e-6, 8);
        assert!(
            t.len() >= 2 && t.iter().all(|v| (1.2e-6..=1.9e-6).contains(v)),
            "{t:?}"
        );
        // Hundreds of decades stay within the limit.
        let t = log_ticks(1e-200, 1e100, 8);
        assert!((2..=8).contains(&t.len()), "{t:?}");
        assert!(log_ticks(0.0, 1.0, 8).is_empty());
    }

    #[test]
    fn log_ticks_have_at_least_two_on_any_span() {
        for (lo, hi) in [
            (1.001, 1.01),
            (5.0, 9.0),
            (0.11, 0.19),
            (7e4, 1.3e5),
            (2.0, 60.0),
        ] {
            let t = log_ticks(lo, hi, 8);
            assert!(t.len() >= 2, "{lo} {hi}: {t:?}");
            assert!(t.iter().all(|v| (lo..=hi).contains(v)), "{lo} {hi}: {t:?}");
        }
    }

    #[test]
    fn a_coord_maps_linear_and_log_without_rounding() {
        let lin = Coord::new(0.0..10.0, Scale::Linear, 8);
        assert_eq!(lin.pixel(2.5, (100, 200)), 125.0);
        assert!((lin.pixel(0.123, (0, 1000)) - 12.3).abs() < 1e-9);
        // y axes run from the bottom pixel up.
        assert_eq!(lin.pixel(2.5, (200, 100)), 175.0);
        let log = Coord::new(1.0..100.0, Scale::Log, 8);
        assert!((log.pixel(10.0, (0, 100)) - 50.0).abs() < 1e-12);
        assert_eq!(log.ticks(), [1.0, 10.0, 100.0]);
        assert_eq!(lin.map(&0.123, (0, 1000)), 12);
    }

    #[test]
    fn tick_labels_are_short() {
        assert_eq!(tick_label(0.0), "0");
        assert_eq!(tick_label(0.5), "0.5");
        assert_eq!(tick_label(20.0), "20");
        assert_eq!(tick_label(1234.5678), "1235");
        assert_eq!(tick_label(0.012345), "0.01235");
        assert_eq!(tick_label(1e-6), "1e-6");
        assert_eq!(tick_label(-2.5e7), "-2.5e7");
    }

    #[test]
    fn ranges_pad_and_validate() {
        let r = axis_range([0.15, 1.2].into_iter(), true);
        assert!((r.start - 0.15 / 1.1).abs() < 1e-15 && r.end > 1.2, "{r:?}");
        assert_eq!(axis_range([0.0, 1.0].into_iter(), false), -0.05..1.05);
        assert_eq!(axis_range(std::iter::empty(), true), 1.0..10.0);
        assert_eq!(valid_range((0.0, 1.0), false), Some(0.0..1.0));
        assert_eq!(valid_range((0.0, 1.0), true), None);
        assert_eq!(valid_range((1.0, 1.0), false), None);
        assert_eq!(valid_range((f64::NAN, 1.0), false), None);
    }
}
