//! Sharded runs: a render cut into contiguous ranges of its work units (the batches of a
//! batch-means render, the realizations of a field render, the configurations of the wave
//! solver), rendered apart (on other machines) and merged into exactly the single run.
//!
//! A shard `i` of `n` holds units `floor(i U / n) .. floor((i + 1) U / n)` of a run of `U`
//! units. It computes them exactly as the single run does (the same streams, the same batches),
//! and keeps what the single run's ordered reduction consumes: each unit's own result (a
//! batch's sums, a realization's fields), never a partial sum of several units, because
//! floating-point addition is not associative. A merge replays the single run's reduction over
//! the units of all shards in unit order ([`crate::MomentsReduction`], [`assemble_rows`]), so
//! its result is bitwise that of the single run for any number of shards and threads.

use crate::CMatrix;
use num_complex::Complex64;
use std::fmt;
use std::ops::Range;
use std::str::FromStr;

/// Shard `index` of `count` of a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Shard {
    /// Which shard, `0 <= index < count`.
    pub index: usize,
    /// Into how many shards the run is cut.
    pub count: usize,
}

/// Most shards a run may be cut into.
pub const MAX_SHARDS: usize = 1 << 20;

impl Shard {
    /// Shard `index` of `count`; the error names `shard`.
    pub fn new(index: usize, count: usize) -> Result<Self, ShardError> {
        if count == 0 || count > MAX_SHARDS {
            return Err(ShardError::Invalid(format!(
                "the number of shards must be in 1..={MAX_SHARDS} (got {count})"
            )));
        }
        if index >= count {
            return Err(ShardError::Invalid(format!(
                "the shard index must be below the number of shards, counting from 0 (got \
                 {index}/{count})"
            )));
        }
        Ok(Self { index, count })
    }

    /// The units of this shard among `total`: `floor(i U / n) .. floor((i + 1) U / n)`
    /// (empty when there are fewer units than shards).
    pub fn units(&self, total: usize) -> Range<usize> {
        let at = |i: usize| (i as u128 * total as u128 / self.count as u128) as usize;
        at(self.index)..at(self.index + 1)
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl FromStr for Shard {
    type Err = ShardError;

    /// `"i/n"`, for example `"3/7"`.
    fn from_str(s: &str) -> Result<Self, ShardError> {
        let bad = || {
            ShardError::Invalid(format!(
                "expected INDEX/COUNT with 0 <= INDEX < COUNT, for example 3/7 (got {s:?})"
            ))
        };
        let (i, n) = s.split_once('/').ok_or_else(bad)?;
        let parse = |t: &str| t.trim().parse::<usize>().map_err(|_| bad());
        Self::new(parse(i)?, parse(n)?)
    }
}

/// Errors of sharding and merging. Shards are named by index (`3/7`) and by their units.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ShardError {
    /// A shard specification is invalid.
    #[error("shard: {0}")]
    Invalid(String),
    /// Nothing to merge.
    #[error("no shards to merge")]
    NoShards,
    /// Units of the run are covered by no shard.
    #[error("{}", missing_message(.missing, *.count, .units, .unit))]
    Missing {
        /// The missing shards' indices, when every shard given is of the same split (else
        /// empty).
        missing: Vec<usize>,
        /// The number of shards of that split (0 when the shards are of several splits).
        count: usize,
        /// The first range of units that no shard covers.
        units: Range<usize>,
        /// The unit's name (`batches`, `realizations`, `configurations`).
        unit: String,
    },
    /// Two shards cover the same units.
    #[error("shards {first} ({unit} {a:?}) and {second} ({unit} {b:?}) overlap", a = .first_units, b = .second_units)]
    Overlap {
        /// One shard.
        first: Shard,
        /// Its units.
        first_units: Range<usize>,
        /// Another shard.
        second: Shard,
        /// Its units.
        second_units: Range<usize>,
        /// The unit's name.
        unit: String,
    },
    /// The shards are not of the same run (different scenes, seeds, sizes or kinds).
    #[error("{0}")]
    Mismatch(String),
}

fn missing_message(missing: &[usize], count: usize, units: &Range<usize>, unit: &str) -> String {
    let list = |v: &[usize]| {
        v.iter()
            .map(|i| format!("{i}/{count}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    match missing {
        [] => format!("no shard covers {unit} {units:?}"),
        [one] => format!(
            "shard {} is missing ({unit} {units:?} are not covered); render it again and merge",
            list(&[*one])
        ),
        many => format!(
            "shards {} are missing ({unit} {units:?} are the first not covered); render them \
             again and merge",
            list(many)
        ),
    }
}

/// Checks that the shards `(shard, units)` of a run of `total` units (`unit` names them) cover
/// every unit exactly once, and returns their positions in unit order. A missing shard is named
/// by its index when all shards are of one split; overlapping shards by theirs.
pub fn order(
    shards: &[(Shard, Range<usize>)],
    total: usize,
    unit: &str,
) -> Result<Vec<usize>, ShardError> {
    if shards.is_empty() {
        return Err(ShardError::NoShards);
    }
    let mut idx: Vec<usize> = (0..shards.len()).collect();
    idx.sort_by_key(|&k| (shards[k].1.start, shards[k].1.end, shards[k].0.index));
    let overlap = |a: usize, b: usize| ShardError::Overlap {
        first: shards[a].0,
        first_units: shards[a].1.clone(),
        second: shards[b].0,
        second_units: shards[b].1.clone(),
        unit: unit.to_string(),
    };
    // The same shard twice (an empty one overlaps nothing, but is still a duplicate).
    for (a, b) in idx.iter().zip(idx.iter().skip(1)) {
        if shards[*a].0 == shards[*b].0 {
            return Err(overlap(*a, *b));
        }
    }
    let count = shards[0].0.count;
    let one_split = shards.iter().all(|s| s.0.count == count);
    let mut next = 0;
    let mut last: Option<usize> = None;
    for &k in &idx {
        let r = &shards[k].1;
        if r.end > total || r.start > r.end {
            return Err(ShardError::Mismatch(format!(
                "shard {} holds {unit} {r:?} of a run of {total}",
                shards[k].0
            )));
        }
        if r.is_empty() {
            continue;
        }
        if r.start < next {
            return Err(overlap(last.unwrap_or(k), k));
        }
        if r.start > next {
            return Err(missing(
                shards,
                next..r.start,
                total,
                one_split.then_some(count),
                unit,
            ));
        }
        next = r.end;
        last = Some(k);
    }
    if next < total {
        return Err(missing(
            shards,
            next..total,
            total,
            one_split.then_some(count),
            unit,
        ));
    }
    Ok(idx)
}

/// The error for `gap` in a run of `total` units: with one split of `count`, every shard of it
/// that holds units and was not given.
fn missing(
    shards: &[(Shard, Range<usize>)],
    gap: Range<usize>,
    total: usize,
    count: Option<usize>,
    unit: &str,
) -> ShardError {
    let (missing, count) = match count {
        Some(n) => {
            let given: std::collections::HashSet<usize> =
                shards.iter().map(|s| s.0.index).collect();
            let missing = (0..n)
                .filter(|&i| {
                    !given.contains(&i) && !Shard { index: i, count: n }.units(total).is_empty()
                })
                .collect();
            (missing, n)
        }
        None => (Vec::new(), 0),
    };
    ShardError::Missing {
        missing,
        count,
        units: gap,
        unit: unit.to_string(),
    }
}

/// Rows of a run's `R x J` matrix (realizations of a field render, configurations of the wave
/// solver) computed by one shard: rows `units` of `total`.
#[derive(Debug, Clone, PartialEq)]
pub struct PartialRows {
    /// Which shard.
    pub shard: Shard,
    /// Its rows among the run's.
    pub units: Range<usize>,
    /// The run's number of rows.
    pub total: usize,
    /// The rows, `units.len() x J`.
    pub rows: CMatrix,
}

/// The run's `total x J` matrix from the rows of its shards, and the shards' positions in row
/// order; errors name missing or overlapping shards (`unit` names the rows).
pub fn assemble_rows(
    parts: &[PartialRows],
    unit: &str,
) -> Result<(CMatrix, Vec<usize>), ShardError> {
    let first = parts.first().ok_or(ShardError::NoShards)?;
    let (total, j) = (first.total, first.rows.cols());
    for p in parts {
        if p.total != total || p.rows.cols() != j || p.rows.rows() != p.units.len() {
            return Err(ShardError::Mismatch(format!(
                "shard {} holds {} x {} values for {unit} {:?} of {} but shard {} is of {total} \
                 {unit} of {j} pairs",
                p.shard,
                p.rows.rows(),
                p.rows.cols(),
                p.units,
                p.total,
                first.shard
            )));
        }
    }
    let ranges: Vec<(Shard, Range<usize>)> =
        parts.iter().map(|p| (p.shard, p.units.clone())).collect();
    let idx = order(&ranges, total, unit)?;
    let mut data = Vec::with_capacity(total * j);
    for &k in &idx {
        data.extend_from_slice(parts[k].rows.as_slice());
    }
    Ok((CMatrix::from_vec(total, j, data), idx))
}

/// Per-pair values (the speckle means) that the shards of a run computed for their shares of
/// the pairs (shard `i` of `n` computes pairs `Shard::units(J)`), so that no shard computes them
/// all: each pair's value is computed alone, so any shard's is bitwise the single run's.
#[derive(Debug, Clone, PartialEq)]
pub struct PairShare {
    /// The pairs.
    pub pairs: Range<usize>,
    /// Their values.
    pub values: Vec<Complex64>,
}

impl PairShare {
    /// The `J` values of a run from its shards' shares (in any order). Overlapping shares must
    /// agree bitwise; pairs no share covers (shards of different counts can leave such gaps)
    /// are computed by `fill` (given each gap).
    pub fn assemble<E: From<ShardError>>(
        shares: &[&PairShare],
        j: usize,
        mut fill: impl FnMut(Range<usize>) -> Result<Vec<Complex64>, E>,
    ) -> Result<Vec<Complex64>, E> {
        let mut out: Vec<Option<Complex64>> = vec![None; j];
        for s in shares {
            if s.pairs.end > j || s.values.len() != s.pairs.len() {
                return Err(ShardError::Mismatch(format!(
                    "a shard holds {} values for pairs {:?} of a run of {j} pairs",
                    s.values.len(),
                    s.pairs
                ))
                .into());
            }
            for (slot, v) in out[s.pairs.clone()].iter_mut().zip(&s.values) {
                match slot {
                    Some(w)
                        if w.re.to_bits() != v.re.to_bits() || w.im.to_bits() != v.im.to_bits() =>
                    {
                        return Err(ShardError::Mismatch(
                            "two shards hold different values for the same pair".into(),
                        )
                        .into());
                    }
                    _ => *slot = Some(*v),
                }
            }
        }
        let mut at = 0;
        while at < j {
            if out[at].is_some() {
                at += 1;
                continue;
            }
            let end = (at..j).find(|&k| out[k].is_some()).unwrap_or(j);
            let values = fill(at..end)?;
            for (slot, v) in out[at..end].iter_mut().zip(values) {
                *slot = Some(v);
            }
            at = end;
        }
        Ok(out.into_iter().map(|v| v.unwrap_or_default()).collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pair_shares_assemble_and_fill_gaps() {
        let c = |x: f64| Complex64::new(x, -x);
        let a = PairShare {
            pairs: 0..2,
            values: vec![c(0.0), c(1.0)],
        };
        let b = PairShare {
            pairs: 3..5,
            values: vec![c(3.0), c(4.0)],
        };
        let mut gaps = Vec::new();
        let v = PairShare::assemble::<ShardError>(&[&b, &a], 5, |r| {
            gaps.push(r.clone());
            Ok(r.map(|k| c(k as f64)).collect())
        })
        .unwrap();
        assert_eq!(v, (0..5).map(|k| c(k as f64)).collect::<Vec<_>>());
        assert_eq!(gaps, vec![2..3]);
        let bad = PairShare {
            pairs: 1..2,
            values: vec![c(7.0)],
        };
        assert!(PairShare::assemble::<ShardError>(&[&a, &bad], 2, |_| Ok(vec![])).is_err());
    }

    #[test]
    fn shards_tile_the_units() {
        for total in [0, 1, 5, 7, 128, 1000] {
            for count in [1, 2, 3, 7, 64, 200] {
                let mut next = 0;
                for index in 0..count {
                    let r = Shard::new(index, count).unwrap().units(total);
                    assert_eq!(r.start, next);
                    next = r.end;
                }
                assert_eq!(next, total);
            }
        }
    }

    #[test]
    fn shard_specifications_are_parsed_and_checked() {
        assert_eq!(
            "3/7".parse::<Shard>().unwrap(),
            Shard { index: 3, count: 7 }
        );
        for bad in ["7/7", "1/0", "x/2", "3", "-1/2", ""] {
            let e = bad.parse::<Shard>().unwrap_err();
            assert!(e.to_string().starts_with("shard: "), "{e}");
        }
    }

    fn split(count: usize, total: usize, skip: &[usize]) -> Vec<(Shard, Range<usize>)> {
        (0..count)
            .filter(|i| !skip.contains(i))
            .map(|i| {
                let s = Shard::new(i, count).unwrap();
                (s, s.units(total))
            })
            .collect()
    }

    #[test]
    fn order_sorts_and_names_missing_and_overlapping_shards() {
        let mut s = split(7, 128, &[]);
        s.reverse();
        let idx = order(&s, 128, "batches").unwrap();
        assert_eq!(idx, (0..7).rev().collect::<Vec<_>>());
        // A missing shard is named by its index.
        let e = order(&split(7, 128, &[3]), 128, "batches").unwrap_err();
        assert!(matches!(&e, ShardError::Missing { missing, count: 7, .. } if missing == &[3]));
        assert!(e.to_string().starts_with("shard 3/7 is missing"), "{e}");
        let e = order(&split(7, 128, &[0, 6]), 128, "batches").unwrap_err();
        assert!(
            e.to_string().starts_with("shards 0/7, 6/7 are missing"),
            "{e}"
        );
        // The same shard twice, or shards of two splits that overlap.
        let mut twice = split(3, 128, &[]);
        twice.push(twice[1].clone());
        let e = order(&twice, 128, "batches").unwrap_err();
        assert!(matches!(e, ShardError::Overlap { .. }), "{e}");
        let mut mixed = split(2, 128, &[1]);
        mixed.extend(split(4, 128, &[0, 1]));
        assert!(
            order(&mixed, 128, "batches").is_ok(),
            "0/2 + 2/4 + 3/4 tile the run"
        );
        mixed.extend(split(3, 128, &[0, 2]));
        let e = order(&mixed, 128, "batches").unwrap_err();
        assert!(e.to_string().contains("overlap"), "{e}");
        // More shards than units: shards 0, 1, 3 and 5 of 7 of 3 units are empty and not
        // needed; a missing non-empty one is named.
        assert!(order(&split(7, 3, &[0, 1, 3, 5]), 3, "configurations").is_ok());
        let e = order(&split(7, 3, &[0, 4]), 3, "configurations").unwrap_err();
        assert!(e.to_string().starts_with("shard 4/7 is missing"), "{e}");
        assert!(matches!(order(&[], 3, "x"), Err(ShardError::NoShards)));
    }
}
