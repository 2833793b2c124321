% Hohmann et al. 2009, Fig. 13: shape grammars in GML.
% As printed, with what the seed's text extraction lost restored: the spaces between the
% symbols ("EDE" is E D E) and the plain hyphens ("terminal—box" is terminal-box).
% C -> E D E -> G F G  F B F  G F G -> 20 terminal boxes (A) and 5 voids (B): a box frame.
ShapeGrammar.Tools.init
/A { terminal-box } def
/B { terminal-void } def
/C { [ 0.1 -1 0.1 ] /X split E D E } def
/D { [ 0.1 -1 0.1 ] /Y split F B F } def
/E { [ 0.1 -1 0.1 ] /Y split G F G } def
/F { [ 0.1 -1 0.1 ] /Z split A B A } def
/G { [ 0.1 -1 0.1 ] /Z split A A A } def
scope (0,0,-2) move (2,1,1) scale C
finish
