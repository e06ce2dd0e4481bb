"""The foundation of every layer: errors, value types, schema checks, scaling, durable writes.

Nothing here imports another amex package, nor Pinocchio, coal, MuJoCo or Hydra.
"""
