"""The wavefront volumetric path tracer: path state (state.py), one kernel file per stage
(listed in stages.py), the SIMD batch of homogeneous medium segments (nee_batch.py) and the
Python driver making the Embree calls (wavefront.py)."""
