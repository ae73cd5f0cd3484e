//! Python bindings of `afe`. Not implemented yet (its own issue); the crate exists so that
//! the workspace has its final shape.
