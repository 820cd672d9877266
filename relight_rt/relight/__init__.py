"""The relighting wing: the ``Relighter`` (``relighter``) and the stages it orders, one module each.

``graphs`` (its ONNX graphs loaded), ``decomposition`` (stage 1's answer, a relight's result, the intrinsic
layers), ``intake`` (photos and masks read for stage 1), ``network`` (the two networks run), ``face_pass`` (the face
pass and the head square on stage 1's skin), ``factor`` (the relighting factor and the exposure), ``strength`` (the
transport's bands restored, the light refit), ``detail`` (guided upsampling), ``look`` (tone and colour rules),
``compose`` (the person over a backdrop), ``light_args`` (a light argument resolved), ``lighting`` (a Decomposition
relit under one light or K), ``people`` (a group relit person by person) and ``transport_file`` (``transport.npz``).
Nothing is imported here: import the module you need.
"""
