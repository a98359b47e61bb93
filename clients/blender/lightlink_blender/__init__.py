"""lightlink for Blender: a live link from Blender to a lightlink daemon (docs/blender.md).

Sidebar (View3D > N panel > Lightlink): daemon address and token, bake options, Connect,
Bake live (exports the scene with Blender's glTF exporter and opens it on the daemon, with a
progress bar and Cancel), Stop. While live, moving, recolouring or changing the power of a
point, spot or sun light, or the emission of a material, sends the change (coalesced, from a timer; no network on Blender's
main thread) and the relit lightmap appears on the meshes through a "LightlinkLM" UV layer
and a node group in their materials.
"""
bl_info = {
    "name": "lightlink",
    "author": "lightlink",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "View3D > Sidebar > Lightlink",
    "description": "Live lightmaps from a lightlink daemon: bake live, move lights, see the result",
    "category": "Lighting",
}

import threading  # noqa: E402

import bpy  # noqa: E402

_link = None          # the LiveLink while connected
_bake_thread = None


def link():
    return _link


def _settings(context):
    return context.scene.lightlink


class LightlinkPreferences(bpy.types.AddonPreferences):
    # In the user preferences, not in the .blend: a shared scene file does not carry the token.
    bl_idname = __name__
    token: bpy.props.StringProperty(name="Token", subtype="PASSWORD", default="",
                                    description="Daemon bearer token (empty: none, or $LIGHTLINK_TOKEN)")

    def draw(self, context):
        self.layout.prop(self, "token")


def _preferences(context):
    addon = context.preferences.addons.get(__name__)
    return addon.preferences if addon is not None else None


class LightlinkSettings(bpy.types.PropertyGroup):
    address: bpy.props.StringProperty(name="Daemon", default="127.0.0.1:50051",
                                      description="host:port of lightlinkd")
    preset: bpy.props.EnumProperty(name="Preset", items=[("draft", "Draft", ""), ("medium", "Medium", ""),
                                                         ("high", "High", "")], default="draft")
    options: bpy.props.StringProperty(name="Options", default="",
                                      description="More bake options, e.g. 'texel-size=0.05 bounces=2'")
    encoding: bpy.props.EnumProperty(
        name="Viewport", default="l1",
        items=[("l1", "SH L1 per pixel", "Irradiance at each pixel's shading normal from SH bands 0 and 1, plus "
                "baked direct (five images)"),
               ("irradiance", "Irradiance", "One image: each texel's SH along its dominant light direction, plus "
                "baked direct")])


def _options(s):
    out = {"preset": s.preset}
    for item in s.options.split():
        if "=" in item:
            k, v = item.split("=", 1)
            out[k.lstrip("-")] = v
    return out


def _ensure_link(context):
    global _link
    from .live import LiveLink

    s = _settings(context)
    prefs = _preferences(context)
    token = (prefs.token if prefs is not None else "") or None
    if _link is not None and (_link.target != s.address or _link.token != token or _link.encoding != s.encoding):
        stop_live()  # another daemon, token or encoding: the old link ends first
    if _link is None:
        _link = LiveLink(s.address, token=token, options=_options(s), encoding=s.encoding)
    _link.options = _options(s)
    return _link


class LIGHTLINK_OT_connect(bpy.types.Operator):
    bl_idname = "lightlink.connect"
    bl_label = "Connect"
    bl_description = "Connect to the daemon and check it answers"

    def execute(self, context):
        try:
            _ensure_link(context).connect()
        except Exception as e:
            self.report({"ERROR"}, f"lightlink: {e}")
            return {"CANCELLED"}
        self.report({"INFO"}, _link.status)
        return {"FINISHED"}


class LIGHTLINK_OT_bake_live(bpy.types.Operator):
    """Export the scene, open it on the daemon (progress; Esc or Cancel stops it) and go live."""
    bl_idname = "lightlink.bake_live"
    bl_label = "Bake live"

    _timer = None

    def invoke(self, context, event):
        global _bake_thread
        lk = _ensure_link(context)
        try:
            if lk.client is None:
                lk.connect()
            # The export reads Blender data: on this thread. The open (network, precompute) runs
            # on a worker; the modal timer shows its progress.
            import os
            import tempfile

            with tempfile.TemporaryDirectory() as tmp:
                lk.glb = lk.export_glb(os.path.join(tmp, "scene.glb"))
        except Exception as e:
            self.report({"ERROR"}, f"lightlink: {e}")
            return {"CANCELLED"}
        self._state = {"done": False, "error": None}

        def run():
            try:
                lk.open_exported()
            except Exception as e:
                self._state["error"] = e
            self._state["done"] = True

        _bake_thread = threading.Thread(target=run, name="lightlink-open", daemon=True)
        _bake_thread.start()
        context.window_manager.progress_begin(0, 100)
        self._timer = context.window_manager.event_timer_add(0.1, window=context.window)
        context.window_manager.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):  # scripts and tests: blocking
        try:
            _ensure_link(context).bake_live()
        except Exception as e:
            self.report({"ERROR"}, f"lightlink: {e}")
            return {"CANCELLED"}
        _start_live()
        return {"FINISHED"}

    def modal(self, context, event):
        lk = _link
        if event.type == "ESC":
            lk.cancel()
        if event.type == "TIMER":
            context.window_manager.progress_update(int(lk.progress * 100))
            for area in context.screen.areas if context.screen else []:
                area.tag_redraw()
            if self._state["done"]:
                context.window_manager.event_timer_remove(self._timer)
                context.window_manager.progress_end()
                if self._state["error"] is not None:
                    lk.status = "failed"
                    self.report({"ERROR"}, f"lightlink: {self._state['error']}")
                    return {"CANCELLED"}
                try:
                    lk.finish_open()
                except Exception as e:
                    self.report({"ERROR"}, f"lightlink: {e}")
                    return {"CANCELLED"}
                _start_live()
                return {"FINISHED"}
        return {"PASS_THROUGH"}


class LIGHTLINK_OT_cancel(bpy.types.Operator):
    bl_idname = "lightlink.cancel"
    bl_label = "Cancel"

    def execute(self, context):
        if _link is not None:
            _link.cancel()
        return {"FINISHED"}


class LIGHTLINK_OT_stop(bpy.types.Operator):
    bl_idname = "lightlink.stop"
    bl_label = "Stop"
    bl_description = "Stop the live link and close the scene on the daemon"

    def execute(self, context):
        stop_live()
        return {"FINISHED"}


class LIGHTLINK_PT_panel(bpy.types.Panel):
    bl_label = "Lightlink"
    bl_idname = "LIGHTLINK_PT_panel"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Lightlink"

    def draw(self, context):
        s = _settings(context)
        col = self.layout.column()
        col.prop(s, "address")
        prefs = _preferences(context)
        if prefs is not None:
            col.prop(prefs, "token")
        col.prop(s, "preset")
        col.prop(s, "options")
        col.prop(s, "encoding")
        row = col.row()
        row.operator("lightlink.connect")
        row.operator("lightlink.bake_live")
        row = col.row()
        row.operator("lightlink.cancel")
        row.operator("lightlink.stop")
        if _link is not None:
            col.label(text=_link.status)
            if _link.applied_version:
                col.label(text=f"version {_link.applied_version}")
            if _link.error:
                col.label(text=_link.error, icon="ERROR")


def _depsgraph_changed(scene, depsgraph):
    lk = _link
    if lk is None or lk.scene is None:
        return
    for u in depsgraph.updates:
        idb = u.id
        if isinstance(idb, bpy.types.Object) and idb.type == "LIGHT":
            lk.light_changed(idb.name)
        elif isinstance(idb, bpy.types.Light):
            for o in bpy.data.objects:
                if o.data == idb:
                    lk.light_changed(o.name)
        elif isinstance(idb, bpy.types.Material):
            lk.material_changed(idb.name)
        elif isinstance(idb, bpy.types.ShaderNodeTree):
            for m in bpy.data.materials:
                if m.node_tree == idb:
                    lk.material_changed(m.name)


def _timer():
    lk = _link
    if lk is None or lk.scene is None:
        return None
    try:
        return lk.tick()
    except Exception as e:  # never let an exception kill the timer silently
        lk.error = str(e)
        return 0.1


@bpy.app.handlers.persistent
def _file_loading(*_args):
    # Another .blend replaces the objects and materials the link maps: it ends (and closes its scene).
    stop_live()


def _start_live():
    if _depsgraph_changed not in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.append(_depsgraph_changed)
    if not bpy.app.timers.is_registered(_timer):
        bpy.app.timers.register(_timer, first_interval=0.02)


def stop_live():
    global _link
    if _depsgraph_changed in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.remove(_depsgraph_changed)
    if bpy.app.timers.is_registered(_timer):
        bpy.app.timers.unregister(_timer)
    if _link is not None:
        _link.stop()
    _link = None


_classes = (LightlinkPreferences, LightlinkSettings, LIGHTLINK_OT_connect, LIGHTLINK_OT_bake_live, LIGHTLINK_OT_cancel,
            LIGHTLINK_OT_stop, LIGHTLINK_PT_panel)


def register():
    for c in _classes:
        bpy.utils.register_class(c)
    bpy.types.Scene.lightlink = bpy.props.PointerProperty(type=LightlinkSettings)
    bpy.app.handlers.load_pre.append(_file_loading)


def unregister():
    stop_live()
    if _file_loading in bpy.app.handlers.load_pre:
        bpy.app.handlers.load_pre.remove(_file_loading)
    del bpy.types.Scene.lightlink
    for c in reversed(_classes):
        bpy.utils.unregister_class(c)
