"""Certificates (schema, hashes), the exact rational re-check and the deployment gate."""
