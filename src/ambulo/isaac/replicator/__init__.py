"""Replicator scripts (``import omni.replicator.core as rep``) run unchanged on ``ambulo.replicator``.

``replicator_names.py`` maps ``omni.replicator.core`` and its sub-APIs to the objects here:
``create``, ``get``, ``modify``, ``randomizer``, ``distribution``, ``trigger``,
``orchestrator``, ``WriterRegistry``/``writers`` (``BasicWriter``), ``AnnotatorRegistry``/``annotators``
(``annotators.py``), ``new_layer`` and ``set_global_seed``. A script's calls build a ``Graph`` (``graph.py``); the orchestrator turns it
into a ``DatasetConfig`` and renders it with ``FrameProducer``, writing BasicWriter's layout.
Older scripts' ``SyntheticDataHelper`` and ``get_active_viewport`` render the World instead.
"""
