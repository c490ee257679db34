//! `samara reproduce --quick`: the report references only files that exist, results.json
//! parses, and a re-run reuses the finished stages.

mod support;
use support::samara;

/// Every `src="..."` and `](...)` target of the reports.
fn referenced_files(html: &str, md: &str) -> Vec<String> {
    let mut v = Vec::new();
    for part in html.split("src=\"").skip(1) {
        v.push(part.split('"').next().unwrap().to_string());
    }
    for part in md.split("](").skip(1) {
        v.push(part.split(')').next().unwrap().to_string());
    }
    v
}

#[test]
fn quick_reproduction_writes_a_consistent_report_and_reuses_stages() {
    let dir = tempfile::tempdir().unwrap();
    let published = concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/reference");
    let run = || {
        samara()
            .args(["reproduce", "--quick", "--json", "--out"])
            .arg(dir.path())
            .arg("--published")
            .arg(published)
            .output()
            .unwrap()
    };
    let out = run();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let results: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("results.json")).unwrap())
            .unwrap();
    assert!(results["stages"]["data"]["rows"].as_u64() == Some(360));
    let html = std::fs::read_to_string(dir.path().join("report.html")).unwrap();
    let md = std::fs::read_to_string(dir.path().join("report.md")).unwrap();
    let refs = referenced_files(&html, &md);
    assert!(!refs.is_empty());
    for r in refs {
        assert!(
            dir.path().join(&r).exists(),
            "report references missing file {r}"
        );
    }
    assert!(md.contains("## Findings"));
    // No temporary files left behind anywhere in the output.
    let mut stack = vec![dir.path().to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                assert!(
                    !p.to_string_lossy().ends_with(".tmp"),
                    "temporary file left: {}",
                    p.display()
                );
            }
        }
    }
    // Second run: everything comes from the cache.
    let out2 = samara()
        .args(["reproduce", "--quick", "--out"])
        .arg(dir.path())
        .arg("--published")
        .arg(published)
        .output()
        .unwrap();
    assert!(out2.status.success());
    assert!(String::from_utf8_lossy(&out2.stderr).contains("reused finished stages"));
}

#[test]
fn bad_published_directory_is_a_usage_error() {
    let dir = tempfile::tempdir().unwrap();
    let out = samara()
        .args(["reproduce", "--quick", "--out"])
        .arg(dir.path())
        .args(["--published", "/nonexistent"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--published"));
}
