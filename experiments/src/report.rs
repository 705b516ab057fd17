//! Rendering `results/README.md`: each experiment's [`Experiment::report`] reads back the
//! CSVs its run wrote (through [`Section`]) and returns curated Markdown tables and its
//! plots; `figures` adds the heading, links every CSV and embeds any plot the report did
//! not place itself, so every PNG of a run appears in the README.
//!
//! [`Experiment::report`]: crate::experiment::Experiment::report

use anyhow::{Context, Result, bail};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// A run's output directory, as the README sees it.
#[derive(Debug, Clone)]
pub struct Section<'a> {
    /// Where the files are.
    pub dir: &'a Path,
    /// The same directory relative to the README (for links).
    pub rel: &'a str,
}

impl Section<'_> {
    /// Path of a file of the run.
    pub fn path(&self, file: &str) -> PathBuf {
        self.dir.join(file)
    }

    /// Reads one of the run's CSVs.
    pub fn csv(&self, file: &str) -> Result<Table> {
        Table::read(&self.path(file))
    }

    /// Markdown that embeds the run's plot `file` (nothing if it was not written).
    pub fn png(&self, file: &str) -> String {
        if self.path(file).exists() {
            format!("![{file}]({}/{file})\n", self.rel)
        } else {
            String::new()
        }
    }

    /// Embeds several plots, one per line.
    pub fn pngs<S: AsRef<str>>(&self, files: impl IntoIterator<Item = S>) -> String {
        files.into_iter().map(|f| self.png(f.as_ref())).collect()
    }
}

/// A CSV file read back: header and rows of strings, cells looked up by column name.
#[derive(Debug, Clone)]
pub struct Table {
    header: Vec<String>,
    rows: Vec<Vec<String>>,
    path: PathBuf,
}

/// One row of a [`Table`].
#[derive(Debug, Clone, Copy)]
pub struct Row<'a> {
    table: &'a Table,
    cells: &'a [String],
}

impl Table {
    /// Reads `path`.
    pub fn read(path: &Path) -> Result<Self> {
        let mut r =
            csv::Reader::from_path(path).with_context(|| format!("reading {}", path.display()))?;
        let header = r
            .headers()
            .with_context(|| format!("reading {}", path.display()))?
            .iter()
            .map(str::to_string)
            .collect();
        let mut rows = Vec::new();
        for rec in r.records() {
            let rec = rec.with_context(|| format!("reading {}", path.display()))?;
            rows.push(rec.iter().map(str::to_string).collect());
        }
        Ok(Self {
            header,
            rows,
            path: path.to_path_buf(),
        })
    }

    /// The rows.
    pub fn rows(&self) -> impl Iterator<Item = Row<'_>> {
        self.rows.iter().map(|cells| Row { table: self, cells })
    }

    /// Whether it has no rows.
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }

    /// The index of column `name`, if the table has it.
    pub fn column(&self, name: &str) -> Option<usize> {
        self.header.iter().position(|h| h == name)
    }

    /// Checks that every column in `names` exists (so a report fails loudly, not silently).
    pub fn require(&self, names: &[&str]) -> Result<()> {
        for n in names {
            if self.column(n).is_none() {
                bail!("{} has no column `{n}`", self.path.display());
            }
        }
        Ok(())
    }

    /// The distinct values of column `name`, in order of appearance.
    pub fn distinct(&self, name: &str) -> Vec<String> {
        let mut v: Vec<String> = Vec::new();
        for r in self.rows() {
            let s = r.get(name);
            if !v.iter().any(|x| x == s) {
                v.push(s.to_string());
            }
        }
        v
    }
}

impl<'a> Row<'a> {
    /// The cell of column `name` ("" if there is no such column).
    pub fn get(&self, name: &str) -> &'a str {
        self.table
            .column(name)
            .and_then(|i| self.cells.get(i))
            .map_or("", String::as_str)
    }

    /// The cell of column `name` as a number (NaN if it is none).
    pub fn num(&self, name: &str) -> f64 {
        self.get(name).parse().unwrap_or(f64::NAN)
    }

    /// The cell as a number with `digits` decimals.
    pub fn fixed(&self, name: &str, digits: usize) -> String {
        fixed(self.num(name), digits)
    }

    /// The cell as a number in scientific notation with `digits` decimals.
    pub fn sci(&self, name: &str, digits: usize) -> String {
        let v = self.num(name);
        if v.is_finite() {
            format!("{v:.digits$e}")
        } else {
            "—".into()
        }
    }

    /// Whether the cell reads `true`.
    pub fn flag(&self, name: &str) -> bool {
        self.get(name) == "true"
    }
}

/// `v` with `digits` decimals, "—" if it is not finite.
pub fn fixed(v: f64, digits: usize) -> String {
    if v.is_finite() {
        format!("{v:.digits$}")
    } else {
        "—".into()
    }
}

/// A Markdown table.
pub fn table<S: AsRef<str>>(header: &[&str], rows: impl IntoIterator<Item = Vec<S>>) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "| {} |", header.join(" | "));
    let _ = writeln!(s, "|{}", "---|".repeat(header.len()));
    for r in rows {
        let cells: Vec<&str> = r.iter().map(AsRef::as_ref).collect();
        let _ = writeln!(s, "| {} |", cells.join(" | "));
    }
    s
}

/// The anisotropy-variant tables of an atlas `points.csv` (issue 12, acceptance 3): for every
/// method `m` that also has points as `m:similarity`, the errors against the path tracer of
/// both variants per scene, g, setting and backend, as one table of the multiple-scattering
/// error (`error_multiple`, what the variant changes) and one of the total image error, and
/// a count of where each variant is closer. `None` if there is no such pair (or no `g`).
pub fn anisotropy_variants(points: &Table) -> Option<String> {
    points
        .require(&[
            "scene",
            "method",
            "setting",
            "backend",
            "g",
            "error",
            "error_multiple",
        ])
        .ok()?;
    let methods = points.distinct("method");
    let bases: Vec<&str> = methods
        .iter()
        .filter_map(|m| m.strip_suffix(":similarity"))
        .filter(|b| methods.iter().any(|m| m == b))
        .collect();
    if bases.is_empty() {
        return None;
    }
    let find = |scene: &str, setting: &str, backend: &str, method: &str| {
        points.rows().find(|r| {
            r.get("scene") == scene
                && r.get("setting") == setting
                && r.get("backend") == backend
                && r.get("method") == method
        })
    };
    let mut header = vec!["scene".to_string(), "g".into(), "setting".into()];
    for b in &bases {
        header.push(format!("{b} paper"));
        header.push(format!("{b} similarity"));
    }
    let header: Vec<&str> = header.iter().map(String::as_str).collect();
    let mut keys: Vec<(String, String, String, String)> = Vec::new();
    for r in points.rows() {
        let k = (
            r.get("scene").to_string(),
            r.get("g").to_string(),
            r.get("setting").to_string(),
            r.get("backend").to_string(),
        );
        if bases.iter().any(|b| r.get("method") == *b) && !keys.contains(&k) {
            keys.push(k);
        }
    }
    // (closer, cases) per base: similarity closer by the multiple-scattering error.
    let mut count = vec![(0usize, 0usize); bases.len()];
    let mut tables = String::new();
    for (column, what) in [
        ("error_multiple", "multiple-scattering image"),
        ("error", "total image"),
    ] {
        let mut rows = Vec::new();
        for (scene, g, setting, backend) in &keys {
            let mut row = vec![scene.clone(), g.clone(), format!("{setting} {backend}")];
            for (i, b) in bases.iter().enumerate() {
                let paper = find(scene, setting, backend, b).map_or(f64::NAN, |r| r.num(column));
                let sim = find(scene, setting, backend, &format!("{b}:similarity"))
                    .map_or(f64::NAN, |r| r.num(column));
                let mark = |x: f64, y: f64| if x < y { "**" } else { "" };
                row.push(format!(
                    "{}{}{}",
                    mark(paper, sim),
                    fixed(paper, 4),
                    mark(paper, sim)
                ));
                row.push(format!(
                    "{}{}{}",
                    mark(sim, paper),
                    fixed(sim, 4),
                    mark(sim, paper)
                ));
                if column == "error_multiple" && paper.is_finite() && sim.is_finite() {
                    count[i].1 += 1;
                    if sim < paper {
                        count[i].0 += 1;
                    }
                }
            }
            rows.push(row);
        }
        let _ = writeln!(
            tables,
            "\n#### Relative RMSE of the {what} against the path tracer, per variant (closer in bold)\n"
        );
        tables.push_str(&table(&header, rows));
    }
    let counts: Vec<String> = bases
        .iter()
        .zip(&count)
        .map(|(b, (sim, n))| format!("{b} in {sim} of {n}"))
        .collect();
    Some(format!(
        "### Anisotropy variants: the paper's σs against the similarity scaling σs' = (1 − g)σs\n\n\
         The similarity scaling is closer to the path tracer's multiple-scattering image in: {}.\n{tables}",
        counts.join(", ")
    ))
}

/// Every PNG under `root`, relative to it, sorted.
pub fn pngs_under(root: &Path) -> Vec<String> {
    fn walk(root: &Path, dir: &Path, out: &mut Vec<String>) {
        let Ok(it) = std::fs::read_dir(dir) else {
            return;
        };
        for e in it.flatten() {
            let p = e.path();
            if p.is_dir() {
                walk(root, &p, out);
            } else if p.extension().is_some_and(|x| x == "png") {
                if let Ok(rel) = p.strip_prefix(root) {
                    out.push(rel.to_string_lossy().replace('\\', "/"));
                }
            }
        }
    }
    let mut v = Vec::new();
    walk(root, root, &mut v);
    v.sort();
    v
}

/// Files in `dir` (not below) whose name ends with `ext`, sorted.
pub fn files_with(dir: &Path, ext: &str) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .map(|it| {
            it.flatten()
                .filter(|e| e.path().is_file())
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .filter(|n| n.ends_with(ext))
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

/// What a README must satisfy: every PNG under `root` embedded (as `](<path>)`), and no
/// line longer than `max_line` characters. Returns the problems found.
pub fn check_readme(readme: &str, root: &Path, max_line: usize) -> Vec<String> {
    let mut problems = Vec::new();
    for p in pngs_under(root) {
        if !readme.contains(&format!("]({p})")) {
            problems.push(format!("{p} is not embedded"));
        }
    }
    for (i, l) in readme.lines().enumerate() {
        let n = l.chars().count();
        if n > max_line {
            problems.push(format!("line {} has {n} characters", i + 1));
        }
    }
    problems
}

/// What `figures` knows of one run when it writes the README.
#[derive(Debug, Clone)]
pub struct RunOutcome {
    /// The experiment.
    pub entry: &'static crate::experiment::ExperimentEntry,
    /// The run.
    pub run: crate::experiment::FigureRun,
    /// Wall time measured by `figures` (`None`: taken from the run's `meta.json`).
    pub seconds: Option<f64>,
    /// Why it was skipped, if it was.
    pub skipped: Option<String>,
    /// Notes printed under its heading.
    pub notes: Vec<String>,
}

impl RunOutcome {
    /// A run not yet made.
    pub fn new(
        entry: &'static crate::experiment::ExperimentEntry,
        run: crate::experiment::FigureRun,
    ) -> Self {
        Self {
            entry,
            run,
            seconds: None,
            skipped: None,
            notes: Vec::new(),
        }
    }
}

fn meta(dir: &Path) -> Option<serde_json::Value> {
    let text = std::fs::read_to_string(dir.join("meta.json")).ok()?;
    serde_json::from_str(&text).ok()
}

/// The whole `results/README.md` for the runs in `outcomes`, whose folders are under `root`:
/// a header with provenance and wall times, then each run's section, the experiment's
/// [`report`](crate::experiment::ExperimentEntry::report) with links to every CSV and any
/// plot it did not embed appended.
pub fn readme(root: &Path, outcomes: &[RunOutcome], quick: bool) -> Result<String> {
    let metas: Vec<Option<serde_json::Value>> = outcomes
        .iter()
        .map(|o| meta(&root.join(&o.run.dir)))
        .collect();
    let first = metas.iter().flatten().next();
    let field = |m: Option<&serde_json::Value>, path: &[&str]| -> String {
        let mut v = m;
        for p in path {
            v = v.and_then(|x| x.get(*p));
        }
        match v {
            Some(serde_json::Value::String(s)) => s.clone(),
            Some(x) => x.to_string(),
            None => "unknown".into(),
        }
    };
    let times: Vec<Option<f64>> = outcomes
        .iter()
        .zip(&metas)
        .map(|(o, m)| {
            o.seconds.or_else(|| {
                m.as_ref()
                    .and_then(|m| m.get("wall_seconds"))
                    .and_then(serde_json::Value::as_f64)
            })
        })
        .collect();
    let total: f64 = times.iter().flatten().fold(0.0, |a, b| a + b);
    // Where each run was made: `figures --only` reruns some folders and keeps the others, so
    // the folders may come from several revisions and hosts; the header must not claim one.
    // (`cpu_id` is in the `meta.json` of runs since 2026-12-08.)
    let origin = |m: &serde_json::Value| {
        let m = Some(m);
        let id = field(m, &["machine", "cpu_id"]);
        format!(
            "`{}` on {}{} ({} cores)",
            field(m, &["git_revision"]),
            field(m, &["machine", "cpu"]),
            if id == "unknown" {
                String::new()
            } else {
                format!(", {id}")
            },
            field(m, &["machine", "logical_cores"]),
        )
    };
    let mut origins: Vec<String> = metas.iter().flatten().map(origin).collect();
    origins.sort();
    origins.dedup();
    let mixed = origins.len() > 1;
    let mut s = String::new();
    let _ = writeln!(s, "# scatterbench results\n");
    let command = format!(
        "`cargo run --release -p experiments --bin figures{}`",
        if quick { " -- --quick" } else { "" }
    );
    if mixed {
        let _ = writeln!(
            s,
            "Generated by {command}, {total:.0} s of runs made at {} different revisions or \
             machines (`figures --only` reruns some folders and keeps the others): the table \
             says where each was made. Every number below was measured in its run; each \
             folder's `meta.json` has its parameters, machine and timings.\n",
            origins.len()
        );
    } else {
        let _ = writeln!(
            s,
            "Generated by {command} at git revision `{}` on {} logical cores, {total:.0} s of \
             runs.",
            field(first, &["git_revision"]),
            field(first, &["machine", "logical_cores"]),
        );
        let _ = writeln!(
            s,
            "Every number below was measured in that run; each folder's `meta.json` has its \
             parameters, machine and timings.\n"
        );
    }
    let rows = outcomes.iter().zip(&times).zip(&metas).map(|((o, t), m)| {
        let mut row = vec![
            format!("`{}`", o.run.dir),
            o.run.title.clone(),
            match (&o.skipped, t) {
                (Some(_), _) => "skipped".into(),
                (None, Some(t)) => format!("{t:.1}"),
                (None, None) => "not run".into(),
            },
        ];
        if mixed {
            row.push(m.as_ref().map_or_else(|| "no meta.json".into(), origin));
        }
        row
    });
    let header: &[&str] = if mixed {
        &["run", "what", "wall time (s)", "made at"]
    } else {
        &["run", "what", "wall time (s)"]
    };
    s.push_str(&table(header, rows));
    for o in outcomes {
        let dir = root.join(&o.run.dir);
        let rel = o.run.dir.as_str();
        let _ = writeln!(s, "\n## {} (`{rel}/`)\n", o.run.title);
        for n in &o.notes {
            let _ = writeln!(s, "{n}\n");
        }
        if let Some(why) = &o.skipped {
            let _ = writeln!(s, "Skipped: {why}");
            continue;
        }
        let section = Section { dir: &dir, rel };
        let body = match o.entry.report(&section) {
            Ok(b) => b,
            Err(e) => format!("No results: {e:#}.\n"),
        };
        s.push_str(body.trim_end());
        s.push('\n');
        let csvs = files_with(&dir, ".csv");
        if !csvs.is_empty() {
            let links: Vec<String> = csvs.iter().map(|c| format!("[`{c}`]({rel}/{c})")).collect();
            let _ = writeln!(s, "\nData: {}.", links.join(", "));
        }
        let rest: Vec<String> = files_with(&dir, ".png")
            .into_iter()
            .filter(|p| !body.contains(&format!("]({rel}/{p})")))
            .collect();
        if !rest.is_empty() {
            let _ = writeln!(s, "\nFurther plots of this run:\n");
            s.push_str(&section.pngs(&rest));
        }
    }
    Ok(wrap(&s, 100))
}

/// Prose lines longer than `width` characters broken at spaces (tables, headings and images
/// are left alone), so that the README reads in a plain editor too.
pub fn wrap(text: &str, width: usize) -> String {
    let mut out = String::with_capacity(text.len());
    for line in text.lines() {
        let keep = line.starts_with('|') || line.starts_with('#') || line.starts_with("![");
        if keep || line.chars().count() <= width {
            out.push_str(line);
            out.push('\n');
            continue;
        }
        let mut len = 0;
        for (k, word) in line.split(' ').enumerate() {
            let n = word.chars().count();
            if k > 0 && len + 1 + n > width {
                out.push('\n');
                len = 0;
            } else if k > 0 {
                out.push(' ');
                len += 1;
            }
            out.push_str(word);
            len += n;
        }
        out.push('\n');
    }
    out
}

/// A device name up to its first parenthesis (`llvmpipe (LLVM 15…)` → `llvmpipe`).
pub fn short_device(name: &str) -> String {
    name.split(" (").next().unwrap_or(name).trim().to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_readme_finds_unembedded_plots_and_long_lines() {
        let root = std::env::temp_dir().join(format!("scatterbench-report-{}", std::process::id()));
        std::fs::create_dir_all(root.join("a/b")).unwrap();
        std::fs::write(root.join("a/x.png"), b"").unwrap();
        std::fs::write(root.join("a/b/y.png"), b"").unwrap();
        let ok = "![x](a/x.png)\n![y](a/b/y.png)\n";
        assert!(check_readme(ok, &root, 300).is_empty());
        let missing = check_readme("![x](a/x.png)\n", &root, 300);
        assert_eq!(missing, ["a/b/y.png is not embedded"]);
        let long = format!("{ok}{}\n", "é".repeat(301));
        assert_eq!(wrap("| a b |\nx yy zzz\n", 4), "| a b |\nx yy\nzzz\n");
        assert_eq!(
            check_readme(&long, &root, 300),
            ["line 3 has 301 characters"]
        );
        let _ = std::fs::remove_dir_all(&root);
    }

    #[test]
    fn anisotropy_variant_tables_pair_each_method_with_its_similarity_twin() {
        let path =
            std::env::temp_dir().join(format!("scatterbench-variants-{}.csv", std::process::id()));
        std::fs::write(
            &path,
            "scene,method,setting,backend,error,error_multiple,g\n\
             a_g0.9,pt,spp=16,cpu-f64,0.1,0.1,0.9\n\
             a_g0.9,cda,ds=4,cpu-f32,0.5,0.8,0.9\n\
             a_g0.9,cda:similarity,ds=4,cpu-f32,0.4,0.3,0.9\n\
             a_g0.3,cda,ds=4,cpu-f32,0.2,0.25,0.3\n\
             a_g0.3,cda:similarity,ds=4,cpu-f32,0.3,0.35,0.3\n\
             a_g0.3,lbm:similarity,ds=4,cpu-f32,0.3,0.35,0.3\n",
        )
        .unwrap();
        let t = Table::read(&path).unwrap();
        let md = anisotropy_variants(&t).unwrap();
        // One pair (cda); lbm:similarity has no paper twin and pt is no variant.
        assert!(md.contains("cda in 1 of 2"), "{md}");
        assert!(!md.contains("lbm") && !md.contains("pt "), "{md}");
        assert!(
            md.contains("| a_g0.9 | 0.9 | ds=4 cpu-f32 | 0.8000 | **0.3000** |"),
            "{md}"
        );
        assert!(
            md.contains("| a_g0.3 | 0.3 | ds=4 cpu-f32 | **0.2000** | 0.3000 |"),
            "{md}"
        );
        std::fs::write(
            &path,
            "scene,method,setting,backend,error,error_multiple,g\n",
        )
        .unwrap();
        assert!(anisotropy_variants(&Table::read(&path).unwrap()).is_none());
        let _ = std::fs::remove_file(&path);
    }

    #[test]
    fn tables_read_back_by_column_name() {
        let path =
            std::env::temp_dir().join(format!("scatterbench-table-{}.csv", std::process::id()));
        std::fs::write(&path, "a,b,flag\n1.23456,x,true\n2,y,false\n").unwrap();
        let t = Table::read(&path).unwrap();
        assert!(t.require(&["a", "b"]).is_ok());
        assert!(t.require(&["c"]).is_err());
        let r: Vec<Row<'_>> = t.rows().collect();
        assert_eq!(
            (r[0].fixed("a", 2), r[0].get("b"), r[0].flag("flag")),
            ("1.23".into(), "x", true)
        );
        assert!(r[1].num("b").is_nan() && !r[1].flag("flag"));
        assert_eq!(t.distinct("b"), ["x", "y"]);
        assert_eq!(
            table(&["h1", "h2"], [vec!["1", "2"]]),
            "| h1 | h2 |\n|---|---|\n| 1 | 2 |\n"
        );
        let _ = std::fs::remove_file(&path);
    }

    /// Folders made at one revision on one machine get the one-run header; a folder rerun
    /// elsewhere (`figures --only`) makes the header say so and the table name each folder's
    /// revision and machine.
    #[test]
    fn the_header_names_each_run_s_origin_once_they_differ() {
        let root = std::env::temp_dir().join(format!("scatterbench-origin-{}", std::process::id()));
        let entry = &crate::experiment::EXPERIMENTS[0];
        let runs = ["one", "two"].map(|d| {
            RunOutcome::new(
                entry,
                crate::experiment::FigureRun::new(d, format!("run {d}")),
            )
        });
        let write = |d: &str, rev: &str, id: &str| {
            std::fs::create_dir_all(root.join(d)).unwrap();
            let m = serde_json::json!({"git_revision": rev, "wall_seconds": 2.0,
                "machine": {"cpu": "AMD EPYC", "cpu_id": id, "logical_cores": 2}});
            std::fs::write(root.join(d).join("meta.json"), m.to_string()).unwrap();
        };
        write("one", "aaa", "family 25 model 1");
        write("two", "aaa", "family 25 model 1");
        // The prose is wrapped at 100 characters: compare with single spaces.
        let flat = |s: String| s.split_whitespace().collect::<Vec<_>>().join(" ");
        let same = flat(readme(&root, &runs, false).unwrap());
        assert!(same.contains("at git revision `aaa` on 2 logical cores, 4 s of runs."));
        assert!(!same.contains("made at"), "{same}");
        write("two", "bbb", "family 26 model 2");
        let mixed = flat(readme(&root, &runs, false).unwrap());
        assert!(
            mixed.contains("made at 2 different revisions or machines"),
            "{mixed}"
        );
        assert!(
            mixed.contains(
                "| `two` | run two | 2.0 | `bbb` on AMD EPYC, family 26 model 2 (2 cores) |"
            ),
            "{mixed}"
        );
        assert!(!mixed.contains("measured in that run"), "{mixed}");
        let _ = std::fs::remove_dir_all(&root);
    }
}
