//! Which runs of a campaign one machine flies: shard `K` of `N` flies the runs whose number,
//! counted from the campaign's first, is `K` modulo `N` (runs dealt round, so every shard gets
//! the same mix of early and late runs and the shards' sizes differ by one at most).

use anyhow::{Context, Result, bail};

/// The environment variables a cluster sets to tell each of a campaign's jobs its index:
/// Kubernetes' Indexed Jobs and AWS Batch's array jobs.
pub const INDEX_VARIABLES: [&str; 2] = ["JOB_COMPLETION_INDEX", "AWS_BATCH_JOB_ARRAY_INDEX"];

/// Shard `index` of `count` (read from a manifest only through [`Shard::new`]'s checks).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(try_from = "ShardFields")]
pub struct Shard {
    /// This shard's number, from 0.
    pub index: u32,
    /// How many shards the campaign is cut into.
    pub count: u32,
}

/// A shard's fields as a manifest has them, before they are checked.
#[derive(serde::Deserialize)]
struct ShardFields {
    index: u32,
    count: u32,
}

impl TryFrom<ShardFields> for Shard {
    type Error = String;

    fn try_from(f: ShardFields) -> Result<Self, String> {
        Shard::new(f.index, f.count).map_err(|e| format!("shard {e}"))
    }
}

impl Shard {
    /// The whole campaign: one shard.
    pub const WHOLE: Shard = Shard { index: 0, count: 1 };

    /// `index` of `count`, refused unless `index < count`.
    pub fn new(index: u32, count: u32) -> Result<Self> {
        if count == 0 {
            bail!("{index}/{count}: a campaign is cut into one shard or more");
        }
        if index >= count {
            bail!(
                "{index}/{count}: shard {index} is not one of the {count} shards (numbered 0 to {})",
                count - 1
            );
        }
        Ok(Self { index, count })
    }

    /// `K/N` as given to `--shard`.
    pub fn parse(text: &str) -> Result<Self> {
        let (k, n) = text
            .split_once('/')
            .with_context(|| format!("{text:?}: expected K/N, shard K of N (from 0)"))?;
        let number = |s: &str, what: &str| {
            s.trim()
                .parse::<u32>()
                .with_context(|| format!("{text:?}: the {what} {s:?} is not a whole number"))
        };
        Self::new(number(k, "index")?, number(n, "count")?)
    }

    /// Shard of `count` whose index the cluster gives in [`INDEX_VARIABLES`] (looked up with
    /// `var`): exactly one of them set, or both set alike.
    pub fn from_cluster(count: u32, var: impl Fn(&str) -> Option<String>) -> Result<Self> {
        let given: Vec<(&str, String)> = INDEX_VARIABLES
            .iter()
            .filter_map(|&name| var(name).map(|v| (name, v)))
            .collect();
        let Some((name, value)) = given.first() else {
            bail!(
                "--shard-count {count} takes the shard's index from {} or {}, and neither is set \
                 (give --shard K/{count} instead)",
                INDEX_VARIABLES[0],
                INDEX_VARIABLES[1]
            );
        };
        if let Some((other, v)) = given.iter().find(|(_, v)| v != value) {
            bail!("{name}={value} and {other}={v} disagree on the shard's index");
        }
        let index = value
            .trim()
            .parse::<u32>()
            .with_context(|| format!("{name}={value:?} is not a shard index"))?;
        Self::new(index, count).with_context(|| format!("{name}={value} with --shard-count"))
    }

    /// Whether run `run` of a campaign starting at `first` is this shard's.
    pub fn holds(&self, first: u32, run: u32) -> bool {
        run >= first && (run - first) % self.count == self.index
    }

    /// This shard's runs of the `runs` runs from `first`, in order.
    pub fn runs(&self, first: u32, runs: u32) -> impl Iterator<Item = u32> {
        let step = self.count as usize;
        (first..first.saturating_add(runs))
            .skip(self.index as usize)
            .step_by(step)
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn shards_deal_every_run_once() {
        let runs = |k, n| Shard::new(k, n).unwrap().runs(10, 200).collect::<Vec<_>>();
        assert_eq!(Shard::WHOLE.runs(10, 200).count(), 200);
        let mut all: Vec<u32> = (0..7).flat_map(|k| runs(k, 7)).collect();
        all.sort_unstable();
        assert_eq!(all, (10..210).collect::<Vec<_>>());
        assert_eq!(runs(3, 7)[..3], [13, 20, 27]);
        assert!((0..7).all(|k| (28..=29).contains(&runs(k, 7).len())));
        assert!(
            runs(3, 7)
                .iter()
                .all(|&r| Shard::new(3, 7).unwrap().holds(10, r))
        );
        assert!(
            runs(250, 300).is_empty(),
            "more shards than runs: some are empty"
        );
    }

    #[test]
    fn bad_shards_are_refused_with_the_reason() {
        let err = |s: &str| format!("{:#}", Shard::parse(s).unwrap_err());
        assert!(
            err("3/2").contains("not one of the 2 shards"),
            "{}",
            err("3/2")
        );
        assert!(err("2/2").contains("numbered 0 to 1"));
        assert!(err("0/0").contains("one shard or more"));
        assert!(err("1").contains("expected K/N"));
        assert!(err("a/4").contains("index \"a\""));
        assert!(err("1/-4").contains("count \"-4\""));
        assert_eq!(Shard::parse(" 6 / 7 ").unwrap(), Shard::new(6, 7).unwrap());
    }

    #[test]
    fn the_index_comes_from_the_clusters_variable() {
        let env = |pairs: &'static [(&'static str, &'static str)]| {
            move |name: &str| {
                pairs
                    .iter()
                    .find(|(n, _)| *n == name)
                    .map(|(_, v)| v.to_string())
            }
        };
        let k8s = Shard::from_cluster(7, env(&[("JOB_COMPLETION_INDEX", "3")])).unwrap();
        assert_eq!(k8s, Shard::new(3, 7).unwrap());
        let aws = Shard::from_cluster(7, env(&[("AWS_BATCH_JOB_ARRAY_INDEX", "6")])).unwrap();
        assert_eq!(aws.index, 6);
        let err = |pairs| format!("{:#}", Shard::from_cluster(7, env(pairs)).unwrap_err());
        assert!(err(&[]).contains("neither is set"));
        assert!(err(&[("JOB_COMPLETION_INDEX", "7")]).contains("not one of the 7"));
        assert!(err(&[("JOB_COMPLETION_INDEX", "x")]).contains("not a shard index"));
        const BOTH: &[(&str, &str)] = &[
            ("JOB_COMPLETION_INDEX", "1"),
            ("AWS_BATCH_JOB_ARRAY_INDEX", "2"),
        ];
        assert!(err(BOTH).contains("disagree"));
    }
}
