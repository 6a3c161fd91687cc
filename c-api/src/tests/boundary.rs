//! Every exported function goes through the panic boundary: a structural check of the
//! sources (like rustls-ffi's one macro per export), since a panic cannot be provoked
//! through the public functions on purpose.

use std::path::Path;

/// Exports that cannot panic and need no boundary: they only return constants or pointers
/// to static data.
const TRIVIAL: &[&str] = &["lq_abi_version", "lq_version", "lq_status_name"];

#[test]
fn every_export_is_guarded() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut exports = 0;
    for entry in std::fs::read_dir(&src).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "rs") {
            continue;
        }
        let text = std::fs::read_to_string(&path).unwrap();
        let mut rest = text.as_str();
        while let Some(at) = rest.find("extern \"C\" fn ") {
            let after = &rest[at + "extern \"C\" fn ".len()..];
            let name: String = after.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect();
            // The body: from the first `{` after the signature to the next top-level `}`.
            let body_start = after.find('{').expect("function body");
            let body_end = after.find("\n}").expect("end of function");
            let body = &after[body_start..body_end];
            exports += 1;
            let guarded = body.contains("guard(") || body.contains("guard_value(");
            let trivial_null_check =
                body.trim_start_matches('{').trim_start().starts_with("if ") && body.contains("guard_value(");
            assert!(
                guarded || trivial_null_check || TRIVIAL.contains(&name.as_str()),
                "{}: `{name}` does not run inside status::guard",
                path.display()
            );
            rest = &after[body_end..];
        }
    }
    // 3 version/status helpers, lq_last_error, 4 material, 12 batch, 4 catalogue/checks,
    // lq_string_free.
    assert!(exports >= 25, "found only {exports} exports");
}
