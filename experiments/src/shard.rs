//! Sharded Monte Carlo runs and their exact merge.
//!
//! A producer (an experiment whose [`Experiment::SHARDS`](crate::experiment::Experiment) is
//! true, or `render --method pt`) computes its Monte Carlo estimates through
//! [`Ctx::tally`](crate::common::Ctx::tally). Run as usual, a tally computes every batch and
//! the producer writes its files. Run with `--shard i/N`, each tally computes only shard i's
//! batches ([`reference::pathtracer::Shard`]) and the run writes, instead of its results, one
//! [`SHARD_FILE`] holding those per-batch sums with their provenance (producer, flags,
//! revision, input-file hashes, shard); the deterministic rest (grid solves, plots) is left
//! to the merge. `merge DIR…` reads the N shard files, refuses sets that do not belong
//! together, joins each tally's batches and reruns the producer with the same flags, its
//! tallies served from the joined sums: the files it writes are the ones an unsharded run
//! writes, bit for bit for every estimate (wall-clock columns aside: a merged tally's
//! seconds are the sum over its shards).
//!
//! File format (little-endian): the magic line `scatterbench-shard 1\n`, a u64 byte length
//! and the JSON [`Header`], then for every tally and part in header order its batch sizes
//! (u64) and its sums (f64, batch-major).

use anyhow::{Context, Result, bail};
use reference::effects::PassSums;
use reference::pathtracer::{BatchSums, Shard};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, VecDeque};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

/// File a shard run writes into its output directory.
pub const SHARD_FILE: &str = "shard.bin";

const MAGIC: &[u8] = b"scatterbench-shard 1\n";

/// Largest header accepted (a shard's header lists its tallies; 64 MiB is far above any).
const MAX_HEADER: u64 = 64 << 20;

/// One named Monte Carlo estimate of a run: the sums of its parts (passes).
#[derive(Debug, Clone, PartialEq)]
pub struct Tally {
    /// What it estimates, as the producer names it (checked on merge).
    pub label: String,
    /// Its parts, each with per-batch sums and seconds.
    pub parts: Vec<PassSums>,
    /// Free text the producer keeps with it (a grid task's iteration counts).
    pub note: String,
}

/// Which task of a sweep a `--task K` run computes, and how many units it has seen.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TaskSel {
    /// K.
    pub index: u32,
    /// Tasks of the sweep.
    pub count: u32,
    /// Units the run has passed so far.
    pub seen: u32,
}

/// How a run's Monte Carlo tallies are obtained.
#[derive(Debug, Default)]
pub enum Mc {
    /// Every batch, here (a normal run).
    #[default]
    Whole,
    /// One shard's batches, stored for the merge.
    Shard {
        /// Which shard.
        shard: Shard,
        /// The producer's flags without `--out` and `--shard`.
        argv: Vec<String>,
        /// Tallies computed so far.
        tallies: Vec<Tally>,
        /// With `--task K`: the one unit of a sweep this run computes (whole, `shard` is
        /// `Shard::WHOLE`); the tallies of every other unit are skipped.
        task: Option<TaskSel>,
    },
    /// Joined from shard files.
    Merge {
        /// Tallies not yet served, in the producer's order.
        tallies: VecDeque<Tally>,
        /// The shards' provenance, for `meta.json`.
        provenance: serde_json::Value,
        /// Whether they are `--task` results (which hold the deterministic units too).
        from_tasks: bool,
    },
}

/// The next stored tally of a merge, which must be the one the run asks for (`label`).
pub(crate) fn next_stored(tallies: &mut VecDeque<Tally>, label: &str) -> Result<Tally> {
    let Some(t) = tallies.pop_front() else {
        bail!("the shards hold fewer tallies than this run takes (next: `{label}`)");
    };
    if t.label != label {
        bail!(
            "the shards' next tally is `{}`, this run's is `{label}`: not shards of this run",
            t.label
        );
    }
    Ok(t)
}

/// Per-part layout in the header.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct PartHeader {
    /// Bins per batch.
    pub bins: usize,
    /// Batches of the whole run.
    pub total_batches: u32,
    /// Samples of the whole run.
    pub total_samples: u64,
    /// First batch held.
    pub first: u32,
    /// Batches held.
    pub batches: u32,
    /// Seconds this shard spent on it.
    pub seconds: f64,
}

/// A tally in the header.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct TallyHeader {
    /// Its label.
    pub label: String,
    /// Its parts.
    pub parts: Vec<PartHeader>,
    /// Its note.
    #[serde(default)]
    pub note: String,
}

/// A shard file's provenance and layout.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Header {
    /// Producer: experiment name or `render`.
    pub producer: String,
    /// Its flags, without `--out` and `--shard`.
    pub argv: Vec<String>,
    /// 0-based shard index.
    pub shard: u32,
    /// Number of shards.
    pub shards: u32,
    /// `git describe` of the build.
    pub git_revision: String,
    /// FNV-1a 64 hashes of the input files named in the flags.
    pub inputs: BTreeMap<String, String>,
    /// The full command line.
    pub command: Vec<String>,
    /// Host and CPU.
    pub machine: serde_json::Value,
    /// The tallies, in the producer's order.
    pub tallies: Vec<TallyHeader>,
    /// With `--task K`: K (the file then holds that task's tallies; `shard`/`shards` are 0/1).
    #[serde(default)]
    pub task: Option<u32>,
    /// With `--task K`: the sweep's number of tasks.
    #[serde(default)]
    pub tasks: Option<u32>,
}

/// `argv` without the flags that do not change results or name the part: `--out X`,
/// `--shard X`, `--task K` (and their `=` forms), `--no-progress` and `--force`.
pub fn strip_flags(argv: &[String]) -> Vec<String> {
    let mut out = Vec::new();
    let mut it = argv.iter();
    while let Some(a) = it.next() {
        if a == "--out" || a == "--shard" || a == "--task" {
            it.next();
        } else if !(a.starts_with("--out=")
            || a.starts_with("--shard=")
            || a.starts_with("--task=")
            || a == "--no-progress"
            || a == "--force")
        {
            out.push(a.clone());
        }
    }
    out
}

/// FNV-1a 64 of `bytes`, as 16 hex digits.
fn fnv1a(bytes: &[u8]) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    format!("{h:016x}")
}

/// Hashes of the regular files the flags name (values, and comma-separated list entries).
pub fn input_hashes(argv: &[String]) -> BTreeMap<String, String> {
    let mut out = BTreeMap::new();
    for a in argv {
        let value = a.split_once('=').map_or(a.as_str(), |(_, v)| v);
        for item in value.split(',') {
            let p = Path::new(item);
            if item.is_empty() || item.starts_with('-') || !p.is_file() {
                continue;
            }
            // Bounded: scene files and volumes; a file that cannot be read is left out (the
            // producer itself reports it).
            if let Ok(bytes) = std::fs::read(p) {
                out.insert(item.to_string(), fnv1a(&bytes));
            }
        }
    }
    out
}

fn put_u64(w: &mut impl Write, v: u64) -> std::io::Result<()> {
    w.write_all(&v.to_le_bytes())
}

/// Writes a shard file atomically (a temporary file renamed into place).
pub fn write(path: &Path, header: &Header, tallies: &[Tally]) -> Result<()> {
    let tmp = path.with_extension("bin.tmp");
    let json = serde_json::to_vec(header).context("serialising the shard header")?;
    let f = std::fs::File::create(&tmp).with_context(|| format!("creating {}", tmp.display()))?;
    let mut w = std::io::BufWriter::new(f);
    let io = (|| -> std::io::Result<()> {
        w.write_all(MAGIC)?;
        put_u64(&mut w, json.len() as u64)?;
        w.write_all(&json)?;
        for t in tallies {
            for p in &t.parts {
                for &n in &p.sums.sizes {
                    put_u64(&mut w, n)?;
                }
                for &s in &p.sums.sums {
                    w.write_all(&s.to_le_bytes())?;
                }
            }
        }
        w.flush()
    })();
    io.with_context(|| format!("writing {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("moving {} into place", tmp.display()))?;
    Ok(())
}

/// A shard file read back.
#[derive(Debug)]
pub struct ShardFile {
    /// Where it was read from.
    pub path: PathBuf,
    /// Its header.
    pub header: Header,
    /// Its tallies.
    pub tallies: Vec<Tally>,
}

fn get_u64(r: &mut impl Read) -> std::io::Result<u64> {
    let mut b = [0u8; 8];
    r.read_exact(&mut b)?;
    Ok(u64::from_le_bytes(b))
}

/// Reads a shard file (`path` may be the file or the shard's output directory).
pub fn read(path: &Path) -> Result<ShardFile> {
    let file = if path.is_dir() {
        path.join(SHARD_FILE)
    } else {
        path.to_path_buf()
    };
    let f = std::fs::File::open(&file).with_context(|| {
        format!(
            "opening shard file {} (did that shard finish? rerun it with the same flags)",
            file.display()
        )
    })?;
    let len = f.metadata().map(|m| m.len()).unwrap_or(0);
    let mut r = std::io::BufReader::new(f);
    let ctx = || format!("reading shard file {}", file.display());
    let mut magic = Vec::with_capacity(MAGIC.len());
    (&mut r)
        .take(MAGIC.len() as u64)
        .read_to_end(&mut magic)
        .with_context(ctx)?;
    if magic != MAGIC {
        bail!("{} is not a scatterbench shard file", file.display());
    }
    let hlen = get_u64(&mut r).with_context(ctx)?;
    if hlen > MAX_HEADER.min(len) {
        bail!("{}: header length {hlen} is corrupt", file.display());
    }
    let mut json = vec![0u8; hlen as usize];
    r.read_exact(&mut json).with_context(ctx)?;
    let header: Header = serde_json::from_slice(&json)
        .with_context(|| format!("{}: corrupt header", file.display()))?;
    let mut payload = 0u64;
    for t in &header.tallies {
        for p in &t.parts {
            payload =
                payload.saturating_add(u64::from(p.batches).saturating_mul(8 + 8 * p.bins as u64));
        }
    }
    if payload != len.saturating_sub(MAGIC.len() as u64 + 8 + hlen) {
        bail!(
            "{}: {} bytes of sums expected from its header, the file holds {} (truncated or \
             corrupt; rerun that shard)",
            file.display(),
            payload,
            len.saturating_sub(MAGIC.len() as u64 + 8 + hlen)
        );
    }
    let mut tallies = Vec::with_capacity(header.tallies.len());
    for t in &header.tallies {
        let mut parts = Vec::with_capacity(t.parts.len());
        for p in &t.parts {
            let sizes = (0..p.batches)
                .map(|_| get_u64(&mut r))
                .collect::<std::io::Result<Vec<u64>>>()
                .with_context(ctx)?;
            let mut sums = vec![0.0; p.batches as usize * p.bins];
            for s in &mut sums {
                *s = f64::from_le_bytes(get_u64(&mut r).with_context(ctx)?.to_le_bytes());
            }
            parts.push(PassSums {
                sums: BatchSums {
                    bins: p.bins,
                    total_batches: p.total_batches,
                    total_samples: p.total_samples,
                    first: p.first,
                    sizes,
                    sums,
                },
                seconds: p.seconds,
            });
        }
        tallies.push(Tally {
            label: t.label.clone(),
            parts,
            note: t.note.clone(),
        });
    }
    Ok(ShardFile {
        path: file,
        header,
        tallies,
    })
}

/// The header of a shard's tallies.
pub fn header(
    producer: &str,
    argv: &[String],
    shard: Shard,
    task: Option<TaskSel>,
    tallies: &[Tally],
) -> Header {
    Header {
        task: task.map(|t| t.index),
        tasks: task.map(|t| t.count),
        producer: producer.to_string(),
        argv: argv.to_vec(),
        shard: shard.index(),
        shards: shard.count(),
        git_revision: crate::common::git_revision(),
        inputs: input_hashes(argv),
        command: std::env::args().collect(),
        machine: crate::common::machine(),
        tallies: tallies
            .iter()
            .map(|t| TallyHeader {
                label: t.label.clone(),
                note: t.note.clone(),
                parts: t
                    .parts
                    .iter()
                    .map(|p| PartHeader {
                        bins: p.sums.bins,
                        total_batches: p.sums.total_batches,
                        total_samples: p.sums.total_samples,
                        first: p.sums.first,
                        batches: p.sums.sizes.len() as u32,
                        seconds: p.seconds,
                    })
                    .collect(),
            })
            .collect(),
    }
}

/// A checked, joined set of shards: the producer, its flags, and its tallies.
#[derive(Debug)]
pub struct Joined {
    /// Producer name.
    pub producer: String,
    /// Its flags.
    pub argv: Vec<String>,
    /// Whole-run tallies in order.
    pub tallies: VecDeque<Tally>,
    /// Provenance of the shards for `meta.json`.
    pub provenance: serde_json::Value,
    /// Whether they are `--task` results.
    pub from_tasks: bool,
}

/// What a set of shard files splits: a run's batches (`--shard`) or a sweep's tasks (`--task`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Split {
    Shards,
    Tasks,
}

impl Split {
    /// (index, count) of a file under this split.
    fn of(self, h: &Header) -> (u32, u32) {
        match self {
            Split::Shards => (h.shard, h.shards),
            Split::Tasks => (h.task.unwrap_or(u32::MAX), h.tasks.unwrap_or(0)),
        }
    }

    /// How an index is named in messages.
    fn name(self, i: u32, count: u32) -> String {
        match self {
            Split::Shards => format!("shard {i}/{count}"),
            Split::Tasks => format!("task {i} of {count}"),
        }
    }
}

/// Checks that `files` are all parts of one run under `split`: same producer, flags,
/// revision and input files (shards: also the same tallies), one count, each index 0..count
/// exactly once. Returns the first header.
fn check_one_run(files: &[ShardFile], split: Split) -> Result<Header> {
    let Some(first) = files.first() else {
        bail!("no shards given");
    };
    let (h0, p0) = (&first.header, &first.path);
    let whole = match split {
        Split::Shards => "shards of one run",
        Split::Tasks => "tasks of one sweep",
    };
    let labels =
        |h: &Header| -> Vec<String> { h.tallies.iter().map(|t| t.label.clone()).collect() };
    let (_, count) = split.of(h0);
    let mut seen: BTreeMap<u32, PathBuf> = BTreeMap::new();
    for f in files {
        let h = &f.header;
        let differ = |what: &str, a: &dyn std::fmt::Debug, b: &dyn std::fmt::Debug| {
            anyhow::anyhow!(
                "{} and {} are not {whole}: their {what} differ ({a:?} vs {b:?})",
                p0.display(),
                f.path.display()
            )
        };
        if h.producer != h0.producer {
            return Err(differ("producers", &h0.producer, &h.producer));
        }
        if h.argv != h0.argv {
            return Err(differ("flags (scene, seed, samples, …)", &h0.argv, &h.argv));
        }
        if h.git_revision != h0.git_revision {
            return Err(differ("revisions", &h0.git_revision, &h.git_revision));
        }
        if h.inputs != h0.inputs {
            return Err(differ("input files", &h0.inputs, &h.inputs));
        }
        if (h.shards, h.tasks) != (h0.shards, h0.tasks) {
            return Err(differ(
                "shard or task counts",
                &(h0.shards, h0.tasks),
                &(h.shards, h.tasks),
            ));
        }
        if split == Split::Shards && labels(h) != labels(h0) {
            return Err(differ("tallies", &labels(h0), &labels(h)));
        }
        let (i, _) = split.of(h);
        if let Some(other) = seen.insert(i, f.path.clone()) {
            bail!(
                "{} is given twice: {} and {}",
                split.name(i, count),
                other.display(),
                f.path.display()
            );
        }
    }
    let missing: Vec<String> = (0..count)
        .filter(|i| !seen.contains_key(i))
        .map(|i| match split {
            Split::Shards => format!("{i}/{count}"),
            Split::Tasks => i.to_string(),
        })
        .collect();
    if !missing.is_empty() {
        let (what, flag, of) = match split {
            Split::Shards => ("shard", "--shard", format!("{count}-shard run")),
            Split::Tasks => ("task", "--task", format!("{count}-task sweep")),
        };
        let many = missing.len() > 1;
        bail!(
            "{what}{} {} of this {of} {} missing: rerun {} with the same flags and `{flag}`, \
             then merge again",
            if many { "s" } else { "" },
            missing.join(", "),
            if many { "are" } else { "is" },
            if many { "them" } else { "it" },
        );
    }
    Ok(h0.clone())
}

/// Checks that `files` are all N shards of one run (same producer, flags, revision, input
/// files and layout, each index 0..N once) and joins their tallies.
pub fn join(files: Vec<ShardFile>) -> Result<Joined> {
    if files.first().is_some_and(|f| f.header.tasks.is_some()) {
        return join_tasks(files);
    }
    let h0 = check_one_run(&files, Split::Shards)?;
    let provenance = serde_json::json!({
        "shards": h0.shards,
        "files": files.iter().map(|f| serde_json::json!({
            "path": f.path.display().to_string(), "shard": f.header.shard,
            "command": f.header.command, "machine": f.header.machine,
        })).collect::<Vec<_>>(),
        "git_revision": h0.git_revision,
        "inputs": h0.inputs,
    });
    let ntallies = h0.tallies.len();
    let mut per_tally: Vec<Vec<Vec<PassSums>>> = vec![Vec::new(); ntallies];
    for f in files {
        for (k, t) in f.tallies.into_iter().enumerate() {
            per_tally[k].push(t.parts);
        }
    }
    let mut tallies = VecDeque::with_capacity(ntallies);
    for (k, shards) in per_tally.into_iter().enumerate() {
        let label = h0.tallies[k].label.clone();
        let nparts = shards.first().map_or(0, Vec::len);
        if shards.iter().any(|s| s.len() != nparts) {
            bail!("tally `{label}`: the shards hold different numbers of passes");
        }
        let mut parts = Vec::with_capacity(nparts);
        for j in 0..nparts {
            let seconds = shards.iter().map(|s| s[j].seconds).sum();
            let sums = BatchSums::join(shards.iter().map(|s| s[j].sums.clone()).collect())
                .with_context(|| format!("tally `{label}`, pass {j}"))?;
            parts.push(PassSums { sums, seconds });
        }
        let note = h0.tallies[k].note.clone();
        tallies.push_back(Tally { label, parts, note });
    }
    Ok(Joined {
        producer: h0.producer,
        argv: h0.argv,
        tallies,
        provenance,
        from_tasks: false,
    })
}

/// Checks that `files` are all T task results of one sweep (same producer, flags, revision,
/// inputs; each task 0..T once) and puts their tallies in task order.
fn join_tasks(mut files: Vec<ShardFile>) -> Result<Joined> {
    let h0 = check_one_run(&files, Split::Tasks)?;
    let count = h0.tasks.unwrap_or(0);
    files.sort_by_key(|f| f.header.task);
    let provenance = serde_json::json!({
        "tasks": count,
        "files": files.iter().map(|f| serde_json::json!({
            "path": f.path.display().to_string(), "task": f.header.task,
            "command": f.header.command, "machine": f.header.machine,
        })).collect::<Vec<_>>(),
        "git_revision": h0.git_revision,
        "inputs": h0.inputs,
    });
    let mut tallies = VecDeque::new();
    for f in files {
        for t in f.tallies {
            if let Some(p) = t.parts.iter().find(|p| !p.sums.is_complete()) {
                bail!(
                    "task tally `{}` holds batches {:?} of {}, not its whole run",
                    t.label,
                    p.sums.batches(),
                    p.sums.total_batches
                );
            }
            tallies.push_back(t);
        }
    }
    Ok(Joined {
        producer: h0.producer,
        argv: h0.argv,
        tallies,
        provenance,
        from_tasks: true,
    })
}

/// Flags of the `merge` binary.
#[derive(Debug, Clone, clap::Parser)]
#[command(
    name = "merge",
    about = "Join the shards of a `--shard i/N` run into the files the unsharded run writes"
)]
pub struct MergeArgs {
    /// Output directory of the merged run (default: the producer's own default, e.g.
    /// `results/pt_slab`).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// The shards: their output directories (or their `shard.bin` files), all N of them.
    #[arg(required = true)]
    pub shards: Vec<PathBuf>,
}

/// Reads, checks and joins the shards, then reruns their producer with its flags (and
/// `--out`, if given) as the merge.
pub fn merge(args: &MergeArgs) -> Result<()> {
    let files = args
        .shards
        .iter()
        .map(|p| read(p))
        .collect::<Result<Vec<_>>>()?;
    let joined = join(files)?;
    let mut argv = joined.argv.clone();
    if let Some(out) = &args.out {
        argv.push("--out".into());
        argv.push(out.display().to_string());
    }
    eprintln!(
        "merge: {} {} of `{} {}`",
        args.shards.len(),
        if joined.from_tasks { "tasks" } else { "shards" },
        joined.producer,
        joined.argv.join(" ")
    );
    if joined.producer == "render" {
        return crate::render::run_merged(&argv, joined);
    }
    match crate::experiment::find(&joined.producer) {
        Some(e) if e.shards => e.run_merged(&argv, joined),
        _ => bail!(
            "the shards name producer `{}`, which this build does not have (producers: {})",
            joined.producer,
            crate::experiment::producers().join(", ")
        ),
    }
}
