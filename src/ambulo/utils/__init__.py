"""Small shared helpers (math on batched quaternions)."""
