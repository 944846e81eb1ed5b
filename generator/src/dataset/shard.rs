//! `--shard K/N`: a deterministic split of the work with no coordination, for
//! Slurm array jobs and Kubernetes indexed jobs.

use super::error::DatasetError;
use std::fmt;
use std::str::FromStr;

/// Shard `index` of `count` (0-based `index`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl Shard {
    pub const ALL: Shard = Shard { index: 0, count: 1 };

    /// Whether the sequence at `position` in the canonical key order belongs
    /// to this shard. Round-robin keeps shards balanced across objects.
    pub fn contains(&self, position: usize) -> bool {
        position % self.count == self.index
    }

    /// Whether two shards (of any counts) share a position: K/N and K'/N'
    /// do exactly when K = K' mod gcd(N, N') (Chinese remainder theorem).
    pub fn overlaps(&self, other: &Shard) -> bool {
        let g = gcd(self.count, other.count);
        self.index % g == other.index % g
    }
}

fn gcd(a: usize, b: usize) -> usize {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

impl FromStr for Shard {
    type Err = DatasetError;
    fn from_str(s: &str) -> Result<Self, DatasetError> {
        let bad = |reason, source| DatasetError::ShardSpec {
            spec: s.to_string(),
            reason,
            source,
        };
        let (k, n) = s
            .split_once('/')
            .ok_or_else(|| bad("expected K/N, e.g. 0/4", None))?;
        let index: usize = k
            .trim()
            .parse()
            .map_err(|e| bad("K is not a number", Some(e)))?;
        let count: usize = n
            .trim()
            .parse()
            .map_err(|e| bad("N is not a number", Some(e)))?;
        if count == 0 || index >= count {
            return Err(bad("need 0 <= K < N", None));
        }
        Ok(Shard { index, count })
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_partition_the_positions() {
        let shards: Vec<Shard> = (0..3).map(|k| format!("{k}/3").parse().unwrap()).collect();
        for pos in 0..100 {
            assert_eq!(shards.iter().filter(|s| s.contains(pos)).count(), 1);
        }
        assert!(Shard::ALL.contains(17));
    }

    #[test]
    fn overlap_is_a_shared_position() {
        let shards: Vec<Shard> = [(0, 1), (0, 2), (1, 2), (1, 4), (3, 4), (2, 3), (5, 6)]
            .iter()
            .map(|&(index, count)| Shard { index, count })
            .collect();
        for a in &shards {
            for b in &shards {
                let shared = (0..a.count * b.count).any(|p| a.contains(p) && b.contains(p));
                assert_eq!(a.overlaps(b), shared, "{a} and {b}");
            }
        }
    }

    #[test]
    fn bad_shards_are_rejected() {
        for bad in ["3/3", "1", "a/2", "0/0", "-1/2"] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
        assert_eq!(
            " 2 / 5".parse::<Shard>().unwrap(),
            Shard { index: 2, count: 5 }
        );
    }
}
