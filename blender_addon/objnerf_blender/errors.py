"""User-facing errors and the operator wrapper that turns them into Blender reports.

Every bad case the add-on can meet (binary not found, a run folder missing files, a render
that fails) raises `ObjnerfError` with a message that names the file or the command; operators
wrap their `execute` with `reports_errors` so the user sees a Blender report, not a traceback.
"""

import functools
import traceback


class ObjnerfError(Exception):
    """An error whose message is written for the user (it names the file or the command)."""


def reports_errors(execute):
    """Decorate an operator's `execute`/`invoke`: errors become `self.report({'ERROR'}, ...)`
    and the operator returns {'CANCELLED'}.

    Unexpected exceptions are reported too (with their type; the traceback goes to the console),
    since a half-finished operator is better explained than dumped.
    """

    def guarded(self, context, *args):
        try:
            return execute(self, context, *args)
        except ObjnerfError as e:
            self.report({"ERROR"}, str(e))
        except (OSError, ValueError, KeyError) as e:
            self.report({"ERROR"}, f"{type(e).__name__}: {e}")
        except Exception as e:  # noqa: BLE001 - see the docstring
            traceback.print_exc()
            self.report({"ERROR"}, f"unexpected {type(e).__name__}: {e} (traceback in the console)")
        return {"CANCELLED"}

    # Blender checks an operator method's argument count when the class is registered, so the
    # wrapper must have the same explicit arguments as the method it wraps.
    if execute.__code__.co_argcount == 3:

        @functools.wraps(execute)
        def wrapper3(self, context, event):
            return guarded(self, context, event)

        return wrapper3

    @functools.wraps(execute)
    def wrapper2(self, context):
        return guarded(self, context)

    return wrapper2
