"""The paper's model as torch modules (Section 5, Table 2): one module, one idea.

Perception and reasoning (issue 12): ``visual_encoder`` (sv), ``scene_encoder`` (sm),
``detection_encoder`` (sl), ``room_classifier`` (sr), ``knowledge_graph`` and
``commonsense`` (sq and the attentions), ``misplaced_detector`` (F_d, fd) and
``receptacle_predictor`` (F_p, fp); ``perception`` composes them.
"""
