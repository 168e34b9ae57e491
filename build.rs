//! Records the source commit the binary is built from (`BFQI_GA_COMMIT`), so run directories
//! can say which code made them: `git rev-parse HEAD`, with `+dirty` when the work tree has
//! uncommitted changes to tracked files, or `unknown` outside a git checkout.
use std::process::Command;

fn git(args: &[&str]) -> Option<String> {
    // `--no-optional-locks`: `git status` would otherwise refresh and rewrite the index it is
    // watched by below, so a fresh clone's first build would make the next one start over.
    let out = Command::new("git").arg("--no-optional-locks").args(args).output().ok()?;
    out.status.success().then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
}

fn main() {
    let commit = match git(&["rev-parse", "HEAD"]) {
        Some(head) if !head.is_empty() => {
            let dirty = git(&["status", "--porcelain", "--untracked-files=no"]).is_some_and(|s| !s.is_empty());
            if dirty { format!("{head}+dirty") } else { head }
        }
        _ => "unknown".to_string(),
    };
    println!("cargo:rustc-env=BFQI_GA_COMMIT={commit}");
    // Re-run when HEAD moves or the index changes (a commit, a checkout, staged edits). Paths
    // come from git itself, so a worktree (where `.git` is a file) watches its own HEAD and index
    // instead of rebuilding on every cargo call.
    let mut watch = vec!["HEAD".to_string(), "index".to_string()];
    if let Some(r) = git(&["symbolic-ref", "-q", "HEAD"]) {
        watch.push(r);
    }
    for name in watch {
        let path = git(&["rev-parse", "--git-path", &name]).unwrap_or_else(|| format!(".git/{name}"));
        println!("cargo:rerun-if-changed={path}");
    }
}
