//! Gives the shared library a SONAME whose number is the ABI major version, so a host linked
//! against `liblacquer.so.0` keeps loading any ABI-compatible build.

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    let os = std::env::var("CARGO_CFG_TARGET_OS").unwrap_or_default();
    if os == "linux" || os == "freebsd" || os == "android" {
        // Keep in step with LQ_ABI_VERSION_MAJOR in src/lib.rs (a test checks it).
        println!("cargo:rustc-cdylib-link-arg=-Wl,-soname,liblacquer.so.0");
    }
}
