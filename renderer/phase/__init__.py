"""Phase functions: the angular distribution of light scattered inside a medium.

Convention everywhere: `d` is the unit PROPAGATION direction of the incoming light path
(the direction the ray travels), `wi` the scattered direction, cos_theta = dot(d, wi), so
g > 0 means forward scattering. A phase function is normalised over the sphere and is
sampled exactly, so its value equals its pdf.
"""
