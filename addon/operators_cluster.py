"""Render Properties > Performance > Test Cluster Connection: which workers would render."""

from __future__ import annotations

import bpy


class HAZE_OT_test_cluster(bpy.types.Operator):
    """Connect to the cluster set in Cluster and report the workers it has (within 5 seconds)"""

    bl_idname = "haze.test_cluster"
    bl_label = "Test Cluster Connection"

    def execute(self, context):
        from renderer.cluster import CONNECT_TIMEOUT, ClusterError, describe

        address = context.scene.haze.cluster
        try:
            text = describe(address, timeout=CONNECT_TIMEOUT)  # never longer: Blender waits on it
        except ClusterError as error:
            self.report({"ERROR"}, f"Haze: {error}")
            return {"CANCELLED"}
        except ImportError as error:  # the extension bundles dask; a bare checkout may lack it
            self.report({"ERROR"}, f"Haze: cluster rendering needs dask and distributed ({error})")
            return {"CANCELLED"}
        self.report({"INFO"}, f"Haze: {text}")
        return {"FINISHED"}


def register() -> None:
    bpy.utils.register_class(HAZE_OT_test_cluster)


def unregister() -> None:
    bpy.utils.unregister_class(HAZE_OT_test_cluster)
