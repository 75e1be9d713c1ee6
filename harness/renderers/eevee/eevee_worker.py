"""eevee_worker.py - one Blender process under a display that renders many EEVEE jobs in turn.

Usage (worker_pool.py starts it, with DISPLAY on its own Xvfb; nothing else should):
    DISPLAY=:N LP_NUM_THREADS=T blender -b --factory-startup --python-exit-code 1 \
        -P eevee_worker.py -- FD
The protocol, the log and the failure line are the Cycles worker's (harness/renderers/cycles/
worker.py, which this runs): a job renders as eevee_render.py renders it in a fresh Blender
(eevee_render.render_job, from the factory settings on). Saved per job: Blender's start-up and
Xvfb's, and EEVEE's shaders when the job's materials compile to code an earlier job compiled
(Blender keeps compiled passes by their code). What gives the same image as a fresh Blender is
checked by tests/eevee_worker.sh.
"""

import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, '..', 'cycles'))
import eevee_render  # noqa: E402  (needs the paths above)
import worker  # noqa: E402

if __name__ == '__main__':
    worker.main(eevee_render.render_job, 'eevee_render.py')
