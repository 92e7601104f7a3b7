"""Empty weak definitions of every function the CI HAL declarations declare
(firmware_stm32/ci/hal_decls): enough to link the HAL-using firmware files, on the host or
the target, with nothing of ST's code. A test double defines the ones it needs for real."""
import re
from pathlib import Path

PROTOTYPE = re.compile(r"^([A-Za-z_][\w ]*?\**)\s*(\w+)\(([^;{]*)\);", re.M)
REGISTER_OBJECT = re.compile(r"^extern (\w+) (ci_\w+);", re.M)


def weak_stubs(decls: Path) -> str:
    """C source: the declarations' headers included, then one weak stub per prototype and
    one weak definition of each register block the declarations make an object."""
    stubs = ['#include "stm32f4xx_hal.h"', '#include "usbd_cdc.h"']
    for header in sorted(decls.glob("*.h")):
        for ret, name, params in PROTOTYPE.findall(header.read_text()):
            body = "" if ret.strip() == "void" else " return 0;"
            stubs.append(f"__attribute__((weak)) {ret} {name}({params}) {{{body} }}")
        for type_name, name in REGISTER_OBJECT.findall(header.read_text()):
            stubs.append(f"__attribute__((weak)) {type_name} {name};")
    return "\n".join(stubs) + "\n"
