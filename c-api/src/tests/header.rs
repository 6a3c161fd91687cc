//! The committed header must be exactly what the pinned cbindgen generates from this crate.

use std::path::PathBuf;

#[test]
fn header_is_up_to_date() {
    let crate_dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let config = cbindgen::Config::from_file(crate_dir.join("cbindgen.toml")).expect("cbindgen.toml parses");
    let mut generated = Vec::new();
    cbindgen::Builder::new()
        .with_crate(&crate_dir)
        .with_config(config)
        .generate()
        .expect("cbindgen generates the header")
        .write(&mut generated);
    let generated = String::from_utf8(generated).expect("UTF-8 header");
    let path = crate_dir.join("include/lacquer.h");
    if std::env::var_os("LACQUER_BLESS_HEADER").is_some() {
        std::fs::write(&path, &generated).expect("write include/lacquer.h");
        return;
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    if committed != generated {
        let first = committed
            .lines()
            .zip(generated.lines())
            .position(|(a, b)| a != b)
            .unwrap_or_else(|| committed.lines().count().min(generated.lines().count()));
        panic!(
            "c-api/include/lacquer.h is out of date (first difference at line {}).\n\
             Regenerate it with: LACQUER_BLESS_HEADER=1 cargo test -p lacquer-capi header",
            first + 1
        );
    }
}

#[test]
fn soname_matches_abi_major() {
    let build = include_str!("../../build.rs");
    let soname = format!("liblacquer.so.{}", crate::LQ_ABI_VERSION_MAJOR);
    assert!(build.contains(&soname), "build.rs must set SONAME {soname}");
}
