" Vim syntax file for RSSM specifications (keywords: grammar/rssm.lark)
if exists("b:current_syntax")
  finish
endif

syntax case match
syntax keyword rssmDeclaration import record enum type const extern device system agent control effector receptor real binding memory param input output behaviour property
syntax keyword rssmStatement update case otherwise when terminal error send receive initial switch let skip if then else always whenever eventually
syntax keyword rssmModifier from to blocking nonblocking
syntax keyword rssmOperatorWord and or not in
syntax keyword rssmBoolean true false
syntax keyword rssmUnit Hz kHz
syntax keyword rssmBuiltin sin cos tan asin acos atan exp log sqrt floor ceil tanh abs atan2 min max clamp norm dot cross new
syntax keyword rssmConstant pi inf
syntax keyword rssmType bool int float
syntax match rssmNumber "\<\d\+\(\.\d*\)\=\([eE][-+]\=\d\+\)\=\>"
syntax region rssmString start=+"+ skip=+\\.+ end=+"\|$+
syntax match rssmOperator ":=\|->\|==\|!=\|<=\|>=\|[-+*/%<>@;|]"
syntax keyword rssmTodo TODO FIXME XXX contained
syntax match rssmComment "//.*$" contains=rssmTodo
syntax region rssmComment start="/\*" end="\*/" contains=rssmTodo

highlight default link rssmDeclaration Keyword
highlight default link rssmStatement Statement
highlight default link rssmModifier StorageClass
highlight default link rssmOperatorWord Operator
highlight default link rssmBoolean Boolean
highlight default link rssmUnit Special
highlight default link rssmBuiltin Function
highlight default link rssmConstant Constant
highlight default link rssmType Type
highlight default link rssmNumber Number
highlight default link rssmString String
highlight default link rssmOperator Operator
highlight default link rssmTodo Todo
highlight default link rssmComment Comment

let b:current_syntax = "rssm"
