"""The YADE adapter: the only package in hmdem that imports YADE (via :mod:`hmdem.yade_env`)."""
