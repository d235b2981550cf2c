"""Flow solvers: implicit/explicit two-phase pore-network model (no YADE here)."""
