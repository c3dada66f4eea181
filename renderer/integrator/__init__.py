"""The wavefront volumetric path tracer: state (state.py), kernels (kernels.py) and the
Python driver making the Embree calls (wavefront.py)."""
