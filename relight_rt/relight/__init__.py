"""The relighting wing: the stages a ``relight_rt.Relighter`` orders, one module each.

``decomposition`` (stage 1's answer, a relight's result, the intrinsic layers), ``intake`` (photos and masks
read for stage 1), ``network`` (the two networks run), ``faces`` (the face pass), ``factor`` (the relighting
factor and the exposure), ``look`` (tone and colour rules), ``compose`` (the person over a backdrop) and
``people`` (a group relit person by person). Nothing is imported here: import the module you need.
"""
