//! Shell nesting (SPEC 8).
