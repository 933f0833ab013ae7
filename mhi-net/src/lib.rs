//! The burn networks of MHI view synthesis (not implemented yet: issue #5).
