"""Driving the interactive (modal) generate operator in headless Blender tests."""

import types


class FakeWindowManager:
    """Timers never fire in background mode: the test delivers the TIMER events itself. Timers,
    modal handlers and progress begin/end are recorded (so a test can check that nothing is left
    behind); anything else is the real window manager's."""

    def __init__(self, real):
        self.real, self.timers, self.handlers, self.progress = real, [], [], []

    def event_timer_add(self, step, window=None):
        self.timers.append(object())
        return self.timers[-1]

    def event_timer_remove(self, timer):
        self.timers.remove(timer)

    def modal_handler_add(self, op):
        self.handlers.append(op)
        return True

    def progress_begin(self, lo, hi):
        self.progress.append("begin")

    def progress_update(self, value):
        pass

    def progress_end(self):
        self.progress.append("end")

    def __getattr__(self, name):
        return getattr(self.real, name)


class FakeArea:
    """An area whose header text the test can read."""

    def __init__(self):
        self.header = None

    def header_text_set(self, text):
        self.header = text


class FakeContext:
    """bpy.context with the fake window manager and area; anything else is the real context."""

    def __init__(self):
        import bpy

        self.window_manager = FakeWindowManager(bpy.context.window_manager)
        self.window = bpy.context.window
        self.area = FakeArea()

    def __getattr__(self, name):
        import bpy

        return getattr(bpy.context, name)


def modal_operator(**props):
    """The generate operator's own methods on a plain object holding its properties (Blender
    cannot create an operator instance outside bpy.ops)."""
    import bpy

    from curveskel_addon.ops_generate import CURVESKEL_OT_generate
    from curveskel_addon.properties import settings_dict

    op = types.SimpleNamespace(**{**settings_dict(bpy.context.scene.curveskel), **props}, reports=[])
    op.report = lambda kind, msg: op.reports.append((set(kind), msg))
    for name in ("_modal_start", "modal", "_modal_end", "_modal_cleanup", "_status", "_checked_source",
                 "_finish"):
        setattr(op, name, types.MethodType(getattr(CURVESKEL_OT_generate, name), op))
    return op


def fake_event(kind, value='NOTHING'):
    """A window-manager event as the modal method reads it."""
    return types.SimpleNamespace(type=kind, value=value)
